"""Host-side construction of Scene, Params and State (NumPy; validates its inputs)."""

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._params import Params
from ._result import Result
from ._scene import Scene
from ._state import State
from .fluid import AbstractSolver, SemiImplicit
from .neighbours import Grid, candidate_counts
from .operators import (
    AbstractGradient,
    AbstractLaplacian,
    AbstractWeight,
    CorrectedGradient,
    MPSWeight,
    StandardLaplacian,
    lattice_offsets,
    reference_constants,
)

# Choice: the default skin of the neighbour lists, in units of l0 (see make_scene).
NEIGHBOUR_SKIN = 0.12


def make_scene(
    position,
    spacing: float,
    domain: tuple,
    *,
    capacity: int | None = None,
    r_e: float = 2.1,
    weight: AbstractWeight = MPSWeight(),
    laplacian: AbstractLaplacian = StandardLaplacian(),
    gradient: AbstractGradient = CorrectedGradient(minimum_shift=True),
    solver: AbstractSolver = SemiImplicit(),
    neighbour_margin: float = 2.0,
    candidate_margin: float = 1.5,
    max_neighbours: int | None = None,
    candidate_capacity: int | None = None,
    reach: int = 2,
    neighbour_skin: float = NEIGHBOUR_SKIN,
    courant_limit: float = 0.5,
    viscous_limit: float = 1.0,
) -> Scene:
    """Build a Scene for the initial particle positions.

    Args:
        position: initial positions of the active particles, shape (m, d).
        spacing: lattice spacing l0 [m].
        domain: (lower, upper) corners of the domain box [m]; particles leaving it
            set `Result.left_domain`.
        capacity: particle slots (>= m); the extra slots form the inactive pool.
        r_e: influence radius in units of l0 (2.1 in seed 000, 2.4 in seed 001).
        weight, laplacian, gradient, solver: the discretisation; see
            `jaxmps.schemes` for the named presets (`standard`, `high_accuracy`).
        neighbour_margin: `max_neighbours` = ceil(margin x lattice neighbour count).
        candidate_margin: `candidate_capacity` = ceil(margin x the most particles
            in the stencil cells of one particle, initially).
        max_neighbours, candidate_capacity: explicit values override the margins.
        reach: the neighbour grid's cells have edge r_e / reach and the stencil
            reaches `reach` cells each way (2, the default, tests about 3x the
            neighbour count as candidates in 2-D; 1 about 4x).
        neighbour_skin: in units of l0; the lists are searched within r_e + skin
            so that `simulate` can carry those of one step's predicted positions to
            the start of the next (`Scene.neighbour_skin`). 0.12 keeps the regular
            lattice's neighbour count (the next lattice distance is sqrt(5) l0 =
            2.236 l0 > 2.1 + 0.12) and is rarely exceeded: the pressure correction
            moved particles by at most 0.04 l0 (explicit) and 0.17 l0 (semi-implicit,
            1 % of the steps beyond 0.06 l0) in the 2-D dam break at l0 = 7.3 mm.
        courant_limit, viscous_limit: stability limits checked every step (see
            `Scene`); `viscous_limit=math.inf` switches the viscous check off.

    Returns:
        The Scene, with n0 and lambda of the regular lattice (DESIGN.md §7).
    """
    position = np.asarray(position, dtype=np.float64)
    if position.ndim != 2 or position.shape[1] not in (2, 3):
        raise ValueError(f"position must have shape (m, 2|3), got {position.shape}.")
    m, dim = position.shape
    if m == 0 and not capacity:
        raise ValueError(
            "make_scene got no particles (position is empty) and no pool "
            "(`capacity`); place at least one particle, e.g. with jaxmps.geometry."
        )
    capacity = m if capacity is None else int(capacity)
    if capacity < m:
        raise ValueError(f"capacity={capacity} is below the {m} initial particles.")
    if not spacing > 0 or not r_e > 1:
        raise ValueError("Need spacing > 0 and r_e > 1 (in units of spacing).")
    lower = np.asarray(domain[0], dtype=np.float64)
    upper = np.asarray(domain[1], dtype=np.float64)
    if lower.shape != (dim,) or upper.shape != (dim,) or np.any(upper <= lower):
        raise ValueError(f"domain must be two corners of a {dim}-D box, lower < upper.")
    if m and (np.any(position < lower) or np.any(position >= upper)):
        raise ValueError(
            "Some initial particles lie outside the domain box; enlarge `domain` "
            "(scene override `domain_margin`)."
        )

    n0, lam = reference_constants(weight, dim, r_e)
    radius = r_e * spacing
    if int(reach) != reach or reach < 1:
        raise ValueError(f"reach must be a positive integer, got {reach!r}.")
    if not neighbour_skin >= 0:
        raise ValueError(f"neighbour_skin must be >= 0, got {neighbour_skin!r}.")
    skin = float(neighbour_skin) * spacing
    cell_size = (radius + skin) / reach
    shape = np.maximum(np.ceil((upper - lower) / cell_size), 1)
    grid = Grid(
        origin=tuple(float(v) for v in lower),
        cell_size=cell_size,
        shape=tuple(int(s) for s in shape),
        candidate_capacity=1,
        reach=int(reach),
    )
    if candidate_capacity is None:
        most = int(candidate_counts(grid, position).max()) if m else 1
        candidate_capacity = max(2, math.ceil(candidate_margin * most))
    grid = eqx.tree_at(lambda g: g.candidate_capacity, grid, int(candidate_capacity))
    if max_neighbours is None:
        lattice_count = len(lattice_offsets(dim, r_e))
        max_neighbours = math.ceil(neighbour_margin * lattice_count)
    return Scene(
        dim=dim,
        capacity=capacity,
        spacing=float(spacing),
        r_e=float(radius),
        n0=n0,
        lam=lam * spacing**2,
        grid=grid,
        max_neighbours=int(max_neighbours),
        neighbour_skin=skin,
        courant_limit=float(courant_limit),
        viscous_limit=float(viscous_limit),
        weight=weight,
        laplacian=laplacian,
        gradient=gradient,
        solver=solver,
    )


def make_params(
    dim: int,
    *,
    dt: float,
    density: float = 1000.0,
    viscosity: float = 1.0e-6,
    gravity: float = 9.81,
    beta: float = 0.97,
    sound_speed: float = 10.0,
    dtype=None,
) -> Params:
    """Params with gravity `gravity` [m/s^2] pointing down the last axis.

    `dtype` defaults to JAX's default float (float32, or float64 with x64 enabled).
    """
    dtype = jnp.zeros(()).dtype if dtype is None else dtype
    g = np.zeros(dim)
    g[-1] = -gravity
    return Params(
        density=jnp.asarray(density, dtype),
        viscosity=jnp.asarray(viscosity, dtype),
        gravity=jnp.asarray(g, dtype),
        dt=jnp.asarray(dt, dtype),
        beta=jnp.asarray(beta, dtype),
        sound_speed=jnp.asarray(sound_speed, dtype),
    )


def make_state(
    scene: Scene,
    position,
    kind,
    *,
    velocity=None,
    pressure=None,
    dtype=None,
) -> State:
    """State holding the given particles first, then inactive pool slots up to capacity.

    Pool slots sit at the domain's lower corner with kind FLUID and `active=False`.
    """
    position = np.asarray(position, dtype=np.float64)
    kind = np.asarray(kind, dtype=np.int32)
    m = position.shape[0]
    if position.shape != (m, scene.dim) or kind.shape != (m,):
        raise ValueError(
            f"position must be (m, {scene.dim}) and kind (m,); got {position.shape} "
            f"and {kind.shape}."
        )
    if m > scene.capacity:
        raise ValueError(f"{m} particles exceed Scene.capacity={scene.capacity}.")
    dtype = jnp.zeros(()).dtype if dtype is None else dtype
    n = scene.capacity
    pos = np.tile(np.asarray(scene.grid.origin), (n, 1))
    pos[:m] = position
    vel = np.zeros((n, scene.dim))
    if velocity is not None:
        vel[:m] = np.asarray(velocity)
    prs = np.zeros(n)
    if pressure is not None:
        prs[:m] = np.asarray(pressure)
    kinds = np.zeros(n, dtype=np.int32)
    kinds[:m] = kind
    active = np.zeros(n, dtype=bool)
    active[:m] = True
    return State(
        time=jnp.asarray(0.0, dtype),
        step=jnp.asarray(0, jnp.int32),
        position=jnp.asarray(pos, dtype),
        velocity=jnp.asarray(vel, dtype),
        pressure=jnp.asarray(prs, dtype),
        kind=jnp.asarray(kinds),
        active=jnp.asarray(active),
        result=Result.successful,
    )


def add_rigid_bodies(
    scene: Scene,
    params: Params,
    state: State,
    body,
    *,
    density,
    mu_static=0.5,
    mu_kinetic=None,
    orientation=None,
    friction="default",
    contact_distance: float = 1.5,
) -> tuple[Scene, Params, State]:
    """Turn particles of a built case into rigid bodies.

    Args:
        scene, params, state: a case without bodies (from `make_scene` etc.).
        body: body index of each initial particle (or of each slot), -1 for none;
            bodies are numbered 0..b-1. Their particles become `Kind.RIGID`; their
            initial velocities are projected onto a rigid motion.
        density: body density [kg/m^3], a scalar or one per body.
        mu_static, mu_kinetic: friction coefficients against walls, a scalar or one
            per body (`mu_kinetic` defaults to `mu_static`, as seed 000 uses).
        orientation: the orientation the particles are given in (angle in degrees
            per body in 2-D, rotation vector in degrees per body in 3-D); the body
            frame is the unrotated one, so reported orientations are absolute.
        friction: a `jaxmps.bodies.Coulomb` law, or None for frictionless contact.
        contact_distance: see `jaxmps.bodies.RigidBodies`.

    Returns:
        The new (scene, params, state).

    Raises:
        ValueError: for body indices that are not 0..b-1, bodies of fewer than two
            particles or with a degenerate inertia, inactive body particles, and
            bodies overlapping each other or walls (closer than 0.5 l0).
    """
    import dataclasses

    from .bodies import Coulomb, RigidBodies, RigidState
    from .bodies import _rotation as rot

    if scene.rigid is not None:
        raise ValueError("This scene already has rigid bodies; add all in one call.")
    n, dim = scene.capacity, scene.dim
    body = np.asarray(body)
    if body.ndim != 1 or body.shape[0] > n or not np.issubdtype(body.dtype, np.integer):
        raise ValueError(
            f"body must be a 1-D integer array of at most {n} entries, got shape "
            f"{body.shape} and dtype {body.dtype}."
        )
    ids = np.full(n, -1, np.int64)
    ids[: body.shape[0]] = body
    count = int(ids.max()) + 1 if ids.max() >= 0 else 0
    if count == 0:
        raise ValueError("body assigns no particle to a body (all entries are -1).")
    present = np.unique(ids[ids >= 0])
    if ids.min() < -1 or len(present) != count:
        raise ValueError(
            f"body indices must be -1 or 0..b-1 with every body present; got "
            f"{sorted(set(ids.tolist()) - {-1})}."
        )
    active = np.asarray(state.active)
    if np.any((ids >= 0) & ~active):
        raise ValueError("body assigns inactive (pool) slots to a body.")

    def per_body(value, name):
        value = np.broadcast_to(np.asarray(value, np.float64), (count,)).copy()
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} must be finite, got {value.tolist()}.")
        return value

    density = per_body(density, "density")
    mu_static = per_body(mu_static, "mu_static")
    mu_kinetic = mu_static if mu_kinetic is None else per_body(mu_kinetic, "mu_kinetic")

    position = np.array(state.position, np.float64)
    velocity = np.array(state.velocity, np.float64)
    kind = np.array(state.kind)
    l0 = scene.spacing
    q_size = rot.orientation_size(dim)
    if orientation is None:
        orient = np.zeros((count, 3 if dim == 3 else 1))
    else:
        orient = np.asarray(orientation, np.float64)
        orient = (
            orient.reshape(count, -1) if orient.ndim else np.full((count, 1), orient)
        )
        if orient.shape != (count, 1 if dim == 2 else 3):
            what = "an angle" if dim == 2 else "a rotation vector"
            raise ValueError(
                f"orientation must give {what} (degrees) per body for {count} "
                f"bodies; got shape {orient.shape}."
            )
    orient = np.deg2rad(orient)
    if dim == 2:
        q = orient
    else:
        q = np.asarray(rot.quaternion_from_rotation_vector(jnp.asarray(orient)))
    rotation = np.asarray(rot.matrix(jnp.asarray(q), dim))

    reference = np.zeros((n, dim))
    centre = np.zeros((count, dim))
    v_body = np.zeros((count, dim))
    w_body = np.zeros((count, rot.spin_size(dim)))
    others = np.where(active & (ids < 0))[0]
    for b in range(count):
        members = np.where(ids == b)[0]
        if len(members) < 2:
            raise ValueError(f"Body {b} has {len(members)} particle(s); need >= 2.")
        c = position[members].mean(axis=0)
        arm = position[members] - c
        inertia = np.asarray(rot.inertia_of(jnp.asarray(arm))).sum(axis=0)
        if (
            np.linalg.det(np.atleast_2d(inertia))
            <= 1e-12 * (len(members) * l0**2) ** (inertia.shape[0])
        ):
            raise ValueError(f"Body {b} has a degenerate (collinear) particle set.")
        centre[b] = c
        reference[members] = arm @ rotation[b]  # R^T arm, row-wise
        v = velocity[members]
        v_body[b] = v.mean(axis=0)
        spin = np.asarray(rot.cross(jnp.asarray(arm), jnp.asarray(v))).sum(axis=0)
        w_body[b] = np.linalg.solve(np.atleast_2d(inertia), np.atleast_1d(spin))
        velocity[members] = v_body[b] + np.asarray(
            rot.spin_cross(jnp.asarray(w_body[b])[None], jnp.asarray(arm))
        )
        kind[members] = 3  # Kind.RIGID
        # Overlaps: other bodies and walls/fluid closer than half a spacing.
        rest = np.concatenate([others, np.where(ids > b)[0]])
        gap = _closest(position[members], position[rest], 0.5 * l0)
        if gap < 0.5 * l0:
            raise ValueError(
                f"Body {b} overlaps other particles (closest at {gap:.3g} m < 0.5 "
                "spacing): move it, or remove the wall or fluid particles it covers."
            )

    friction_law = Coulomb() if friction == "default" else friction
    new_scene = dataclasses.replace(
        scene,
        rigid=RigidBodies(
            count=count, friction=friction_law, contact_distance=contact_distance
        ),
    )
    dtype = params.density.dtype
    from ._params import RigidParams

    new_params = dataclasses.replace(
        params,
        rigid=RigidParams(
            density=jnp.asarray(density, dtype),
            mu_static=jnp.asarray(mu_static, dtype),
            mu_kinetic=jnp.asarray(mu_kinetic, dtype),
        ),
    )
    fdtype = state.position.dtype
    zeros_b = jnp.zeros((count, dim), fdtype)
    rigid = RigidState(
        body=jnp.asarray(ids, jnp.int32),
        reference=jnp.asarray(reference, fdtype),
        centre=jnp.asarray(centre, fdtype),
        orientation=jnp.asarray(np.asarray(q).reshape(count, q_size), fdtype),
        velocity=jnp.asarray(v_body, fdtype),
        angular_velocity=jnp.asarray(w_body, fdtype),
        force=zeros_b,
        torque=jnp.zeros_like(jnp.asarray(w_body, fdtype)),
        contact_force=zeros_b,
        impulse=zeros_b,
        angular_impulse=jnp.zeros_like(jnp.asarray(w_body, fdtype)),
        friction=zeros_b,
        sliding=jnp.zeros((count,), bool),
        particle_contact=jnp.zeros((n, dim), fdtype),
        particle_normal=jnp.zeros((n, dim), fdtype),
    )
    new_state = dataclasses.replace(
        state,
        kind=jnp.asarray(kind, state.kind.dtype),
        velocity=jnp.asarray(velocity, fdtype),
        rigid=rigid,
    )
    return new_scene, new_params, new_state


def _closest(a: np.ndarray, b: np.ndarray, cutoff: float) -> float:
    """Smallest distance between points of `a` and `b` if below `cutoff`, else inf
    (only points of `b` in the box of `a` widened by `cutoff` are compared)."""
    if len(a) == 0 or len(b) == 0:
        return math.inf
    near = np.all((b >= a.min(0) - cutoff) & (b <= a.max(0) + cutoff), axis=1)
    b = b[near]
    best = math.inf
    for start in range(0, len(b), 512):
        chunk = b[start : start + 512]
        d = np.linalg.norm(a[:, None, :] - chunk[None, :, :], axis=-1)
        best = min(best, float(d.min()))
    return best
