"""Host-side construction of Scene, Params and State (NumPy; validates its inputs)."""

import dataclasses
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from . import bodies, schemes
from ._params import ElasticParams, Params, RigidParams, check_values
from ._result import Result
from ._scene import Scene
from ._state import State
from ._stepping import Adaptive
from ._types import Kind
from .neighbours import Grid, candidate_counts
from .operators import Discretisation, lattice_offsets, reference_constants

# Choice: the default skin of the neighbour lists, in units of l0 (see make_scene).
NEIGHBOUR_SKIN = 0.3
# Choice: the default slots hold the pairs within (r_e + skin)(1 + SKIN_SLACK) of a
# regular lattice, so that a flow a little denser than the lattice keeps its lists
# carried. In 3-D the lattice's shell at sqrt(6) = 2.45 l0 (24 pairs) lies 2 %
# beyond r_e + skin = 2.4 l0: with 64 slots a compression of 2 % made every
# search fall back to the pairs within r_e (benchmarks/NOTES.md §14).
SKIN_SLACK = 0.05
# Choice: the share of the elastic step limit a sub-step takes by default (the
# share adaptive steps take of the hard limits, `Adaptive.stability`).
# Choice: default sub-steps at a quarter of the sub-step limit. Measured: a dense
# plate (4 layers, nu = 0.3) at h c_s / l0 = 0.11 (the limit's half) grew a spin
# mode over 8000 sub-steps (0.3 s) to 3e3 rad/s; at 0.074 it stayed calm over
# 95 000; the onsets of the stability map (0.29-0.46) are of 0.15 s runs.
SUBSTEP_MARGIN = 0.25
MAX_CELLS = 2**31 - 1


def make_scene(
    position,
    spacing: float,
    domain: tuple,
    *,
    scheme: schemes.Scheme | None = None,
    capacity: int | None = None,
    neighbour_margin: float = 2.0,
    candidate_margin: float = 1.5,
    max_neighbours: int | None = None,
    candidate_capacity: int | None = None,
    reach: int = 2,
    neighbour_skin: float = NEIGHBOUR_SKIN,
    courant_limit: float = 0.5,
    viscous_limit: float = 1.0,
    time_step: Adaptive | None = None,
    escape_limit: int = 0,
) -> Scene:
    """Build a Scene for the initial particle positions.

    Args:
        position: initial positions of the active particles, shape (m, d).
        spacing: lattice spacing l0 [m].
        domain: (lower, upper) corners of the domain box [m]; particles leaving it
            set `Result.left_domain`.
        scheme: the discretisation (influence radius, operators, pressure stage):
            a `jaxmps.schemes` preset, `schemes.standard()` by default.
        capacity: particle slots (>= m); the extra slots form the inactive pool.
        neighbour_margin: `max_neighbours` = ceil(margin x lattice neighbour count),
            at least the lattice's pairs in reach of the skin (`_slots`: 24, 80).
        candidate_margin: `candidate_capacity` = ceil(margin x the most particles
            in the stencil cells of one particle, initially or in a filled
            regular lattice, whichever is more).
        max_neighbours, candidate_capacity: explicit values override the margins.
        reach: the neighbour grid's cells have edge r_e / reach and the stencil
            reaches `reach` cells each way (2, the default, tests about 3x the
            neighbour count as candidates in 2-D; 1 about 4x).
        neighbour_skin: in units of l0; the lists are searched within r_e + skin
            so that `simulate` can carry them from search to search until some
            pair has moved apart or together by the skin (`Scene.neighbour_skin`,
            `neighbours.lists_hold`). Where
            the skin's pairs do not fit in `max_neighbours` slots, a search lists
            those within r_e only and the next one searches again. 0.3 holds the
            regular lattice's pairs within 2.4 l0 (20 in 2-D, 56 in 3-D, within the
            default 24 and 80 slots) and carries the lists over the 0.1 l0 a fast
            particle moves in an explicit step (2-D dam break, 25k particles,
            float64: 22.3 -> 8.8 ms per step over the first 200 steps, 26.3 ->
            16.3 ms at 0.22 s; 0.12 l0 gave 10.5 and 27.5 ms; benchmarks/NOTES.md
            §13).
        courant_limit, viscous_limit: stability limits checked every step (see
            `Scene`); `viscous_limit=math.inf` switches the viscous check off.
        escape_limit: fluid particles that may leave the domain and be taken
            out of the run (`Scene.escape_limit`); 0 ends the run at the first.
        time_step: None (the default) steps by `Params.dt`; `jaxmps.Adaptive()`
            chooses each step's dt from the flow, at most `Params.dt` (the built-in
            scenes do, unless given `dt` in seconds).

    Returns:
        The Scene, with n0 and lambda of the regular lattice.
    """
    position = np.asarray(position, dtype=np.float64)
    if position.ndim == 2 and not np.all(np.isfinite(position)):
        rows = np.flatnonzero(~np.all(np.isfinite(position), axis=1))
        raise ValueError(
            f"position holds non-finite coordinates (rows {rows[:5].tolist()}"
            f"{', ...' if len(rows) > 5 else ''}); give every particle a place."
        )
    capacity = _capacity(position, capacity)
    scheme = schemes.standard() if scheme is None else scheme
    if not (spacing > 0 and math.isfinite(spacing * spacing)):
        raise ValueError(f"spacing must be positive and finite, got {spacing!r}.")
    dim = position.shape[1]
    discretisation = _discretisation(scheme, dim, spacing)
    if not neighbour_skin >= 0:
        raise ValueError(f"neighbour_skin must be >= 0, got {neighbour_skin!r}.")
    skin = float(neighbour_skin) * spacing
    grid = _grid(position, domain, discretisation.r_e + skin, reach)
    if candidate_capacity is None:
        candidate_capacity = _candidates(grid, position, spacing, candidate_margin)
    grid = eqx.tree_at(lambda g: g.candidate_capacity, grid, int(candidate_capacity))
    if max_neighbours is None:
        max_neighbours = _slots(dim, scheme.r_e, neighbour_margin, neighbour_skin)
    return Scene(
        discretisation=discretisation,
        capacity=capacity,
        grid=grid,
        max_neighbours=int(max_neighbours),
        neighbour_skin=skin,
        courant_limit=float(courant_limit),
        viscous_limit=float(viscous_limit),
        laplacian=scheme.laplacian,
        gradient=scheme.gradient,
        solver=scheme.solver,
        surface=scheme.surface,
        collision=scheme.collision,
        stabiliser=scheme.stabiliser,
        time_step=time_step,
        escape_limit=int(escape_limit),
    )


def _discretisation(scheme: schemes.Scheme, dim: int, spacing: float):
    """The scheme's weight and influence radius at `spacing`, with n0 and lambda
    of the regular lattice."""
    n0, lam = reference_constants(scheme.weight, dim, scheme.r_e)
    return Discretisation(
        dim=dim,
        spacing=float(spacing),
        r_e=float(scheme.r_e * spacing),
        n0=n0,
        lam=lam * spacing**2,
        weight=scheme.weight,
    )


def _slots(dim: int, r_e: float, margin: float, skin: float) -> int:
    """Default neighbour slots (r_e and skin in units of l0): `margin` times the
    regular lattice's pairs within r_e, and with a skin at least the lattice's
    pairs within (r_e + skin)(1 + `SKIN_SLACK`)."""
    slots = math.ceil(margin * len(lattice_offsets(dim, r_e)))
    if skin > 0:
        within = (r_e + float(skin)) * (1 + SKIN_SLACK)
        slots = max(slots, len(lattice_offsets(dim, within)))
    return slots


def _candidates(grid: Grid, position: np.ndarray, spacing: float, margin: float) -> int:
    """The default `Grid.candidate_capacity`: `margin` x the most particles in one
    particle's stencil cells, initially or in a filled lattice (`_filled_stencil`)."""
    most = int(candidate_counts(grid, position).max()) if len(position) else 1
    most = max(most, _filled_stencil(grid, spacing))
    return max(2, math.ceil(margin * most))


def _filled_stencil(grid: Grid, spacing: float) -> int:
    """The most particles of a regular lattice of `spacing` in the stencil cells of
    one particle: what fluid brings where it flows into a part of the domain that
    starts empty or holds walls only (a dry bed fed by an inflow, a splash).

    Choice: candidates are sized for the larger of this and the initial state's
    count. Measured: a flume fed over a dry bed (l0 = 7.5 mm) started with at most
    27 candidates (the bed's walls) and reached 42 once water ran over the bed,
    beyond 1.5 x 27; a filled lattice gives 36 (cells of 1.2 l0)."""
    across = (2 * grid.reach + 1) * grid.cell_size / spacing
    return math.ceil(across - 1e-9) ** len(grid.shape)


def _capacity(position: np.ndarray, capacity: int | None) -> int:
    """The particle slots: `capacity`, or the number of particles; refuses a
    position array that is not (m, 2|3), no particles and no pool, and a capacity
    below the particle count."""
    if position.ndim != 2 or position.shape[1] not in (2, 3):
        raise ValueError(f"position must have shape (m, 2|3), got {position.shape}.")
    m = position.shape[0]
    if m == 0 and not capacity:
        raise ValueError(
            "make_scene got no particles (position is empty) and no pool "
            "(`capacity`); place at least one particle, e.g. with jaxmps.geometry."
        )
    capacity = m if capacity is None else int(capacity)
    if capacity < m:
        raise ValueError(f"capacity={capacity} is below the {m} initial particles.")
    return capacity


def _grid(position: np.ndarray, domain, radius: float, reach) -> Grid:
    """The neighbour-search grid over the domain box, for a search radius `radius`
    (cells of edge radius / reach); refuses a box that is not one, or that does not
    hold every initial particle."""
    dim = position.shape[1]
    lower = np.asarray(domain[0], dtype=np.float64)
    upper = np.asarray(domain[1], dtype=np.float64)
    if lower.shape != (dim,) or upper.shape != (dim,) or np.any(upper <= lower):
        raise ValueError(f"domain must be two corners of a {dim}-D box, lower < upper.")
    if len(position) and (np.any(position < lower) or np.any(position >= upper)):
        raise ValueError(
            "Some initial particles lie outside the domain box; enlarge `domain` "
            "(scene override `domain_margin`)."
        )
    if int(reach) != reach or reach < 1:
        raise ValueError(f"reach must be a positive integer, got {reach!r}.")
    cell_size = radius / reach
    shape = np.maximum(np.ceil((upper - lower) / cell_size), 1)
    cells = float(np.prod(shape + 2 * reach))
    if cells > MAX_CELLS:
        raise ValueError(
            f"The domain box spans {cells:.3g} neighbour-search cells of "
            f"{cell_size:.3g} m (at most {MAX_CELLS:.3g}: cells are numbered in "
            "int32): shrink `domain` (scene override `domain_margin`), or coarsen "
            "`spacing`."
        )
    return Grid(
        origin=tuple(float(v) for v in lower),
        cell_size=cell_size,
        shape=tuple(int(s) for s in shape),
        candidate_capacity=1,
        reach=int(reach),
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
    relaxation_step: float | None = None,
    dtype=None,
) -> Params:
    """Params with gravity `gravity` [m/s^2] pointing down the last axis
    (`relaxation_step`: see `Params`; None relaxes the density per step of `dt`).

    `dtype` defaults to JAX's default float (float32, or float64 with x64 enabled).
    """
    if dim not in (2, 3):
        raise ValueError(f"make_params: dim must be 2 or 3, got {dim!r}.")
    if np.ndim(gravity) != 0 or gravity < 0:  # (not finite: Params says so)
        raise ValueError(
            f"make_params: gravity is its magnitude [m/s^2], pointing down the "
            f"last axis: a number >= 0, got {gravity!r} (another direction: set "
            "Params.gravity, a vector, e.g. with equinox.tree_at)."
        )
    dtype = jnp.zeros(()).dtype if dtype is None else dtype
    g = np.zeros(dim)
    g[-1] = -gravity
    params = Params(
        density=jnp.asarray(density, dtype),
        viscosity=jnp.asarray(viscosity, dtype),
        gravity=jnp.asarray(g, dtype),
        dt=jnp.asarray(dt, dtype),
        beta=jnp.asarray(beta, dtype),
        sound_speed=jnp.asarray(sound_speed, dtype),
        relaxation_step=(
            None if relaxation_step is None else jnp.asarray(relaxation_step, dtype)
        ),
    )
    check_values(params, "make_params: ")
    return params


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
    `kind` holds `jaxmps.Kind` values (rigid-body particles are made by
    `add_rigid_bodies`).
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
    known = [int(k) for k in Kind]
    unknown = sorted(set(np.unique(kind).tolist()) - set(known))
    if unknown:
        raise ValueError(
            f"kind holds {unknown}, which are not particle kinds; valid: "
            + ", ".join(f"{int(k)} ({k.name.lower()})" for k in Kind)
            + "."
        )
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
        dt=jnp.asarray(0.0, dtype),
        acceleration=jnp.asarray(0.0, dtype),
        escaped=jnp.asarray(0, jnp.int32),
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
    centre_of_mass=None,
    gyration=None,
    friction: bodies.Coulomb | None = bodies.RigidBodies.friction,
    contact_distance: float = bodies.RigidBodies.contact_distance,
    pressure: str = bodies.RigidBodies.pressure,
    contact_stiffness: float = bodies.RigidBodies.contact_stiffness,
    contact_damping: float = bodies.RigidBodies.contact_damping,
    friction_sweeps: int = bodies.RigidBodies.friction_sweeps,
    release_time=None,
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
        centre_of_mass: where the centre of mass lies from the centroid of the
            body's particles, in the body frame [m]: d values for all bodies or per
            body; None for a uniform body (`Params.rigid.centre_of_mass`).
        gyration: radii of gyration about the centre of mass [m] (about z in 2-D;
            about the body-frame axes in 3-D), for all bodies or per body; None for
            the inertia of the body's particles (`Params.rigid.gyration`).
        friction: a `jaxmps.bodies.Coulomb` law, or None for frictionless contact.
        contact_distance, friction_sweeps and the defaults: see
            `jaxmps.bodies.RigidBodies`.
        pressure: how the pressure acts on the bodies, "pairs" (contact and
            friction) or "fluid" (floating bodies at Archimedes' draft); see
            `jaxmps.bodies.RigidBodies`.
        contact_stiffness, contact_damping: the contact force's stiffness (a
            fraction of the step's explicit limit; 0 leaves contact to the
            pressure) and damping ratio; see `jaxmps.bodies.RigidBodies`.
        release_time: the bodies are held still until then [s] (a scalar or one
            per body; `Params.rigid.release_time`); None: free from the start.

    Returns:
        The new (scene, params, state).

    Raises:
        ValueError: for body indices that are not 0..b-1, bodies of fewer than two
            particles or with a degenerate inertia, inactive body particles, and
            bodies overlapping each other or walls (closer than 0.5 l0).
    """
    _refuse_second_rigid(scene)
    active = np.asarray(state.active)
    ids, count = bodies.body_indices(body, scene.capacity, active)
    rigid_params = _rigid_params(params, count, density, mu_static, mu_kinetic)
    rigid_params = _mass_properties(
        rigid_params, count, scene.dim, centre_of_mass, gyration
    )
    rigid_params = _release_times(rigid_params, count, release_time)
    rigid, kind, velocity = bodies.rigid_state(
        np.array(state.position, np.float64),
        np.array(state.velocity, np.float64),
        np.array(state.kind),
        active,
        ids,
        count,
        bodies.orientations(orientation, count, scene.dim),
        scene.spacing,
        state.position.dtype,
    )
    model = bodies.RigidBodies(
        count=count,
        friction=friction,
        contact_distance=contact_distance,
        pressure=pressure,
        contact_stiffness=contact_stiffness,
        contact_damping=contact_damping,
        friction_sweeps=friction_sweeps,
        particles=int(np.sum(np.asarray(ids) >= 0)),
    )
    new_state = dataclasses.replace(
        state,
        kind=jnp.asarray(kind, state.kind.dtype),
        velocity=jnp.asarray(velocity, state.position.dtype),
        rigid=rigid,
    )
    return (
        dataclasses.replace(scene, rigid=model),
        dataclasses.replace(params, rigid=rigid_params),
        new_state,
    )


def _release_times(rigid: RigidParams, count: int, release_time) -> RigidParams:
    """`rigid` with the bodies' release times (None: free from the start)."""
    if release_time is None:
        return rigid
    release = bodies.per_body(release_time, "release_time", count)
    if not np.all(release >= 0):
        raise ValueError(f"release_time must be >= 0 [s], got {release_time}.")
    return dataclasses.replace(
        rigid, release_time=jnp.asarray(release, rigid.density.dtype)
    )


def _refuse_second_rigid(scene: Scene) -> None:
    """Rigid bodies are added once, and before elastic ones."""
    if scene.rigid is not None:
        raise ValueError("This scene already has rigid bodies; add all in one call.")
    if scene.elastic is not None:
        raise ValueError(
            "Add rigid bodies before elastic ones (the rigid bodies are numbered "
            "first)."
        )


def _mass_properties(
    rigid: RigidParams, count: int, dim: int, centre_of_mass, gyration
) -> RigidParams:
    """`rigid` with the bodies' given centres of mass and radii of gyration (None:
    those of their particles), checked and in its dtype."""
    spin = bodies.rotation.spin_size(dim)
    rows = {
        "centre_of_mass": bodies.per_body_rows(
            centre_of_mass, "centre_of_mass", count, dim
        ),
        "gyration": bodies.per_body_rows(gyration, "gyration", count, spin),
    }
    if rows["gyration"] is not None and not np.all(rows["gyration"] > 0):
        raise ValueError(f"gyration must be positive, got {gyration}.")
    dtype = rigid.density.dtype
    return dataclasses.replace(
        rigid,
        **{k: None if v is None else jnp.asarray(v, dtype) for k, v in rows.items()},
    )


def _rigid_params(params: Params, count: int, density, mu_static, mu_kinetic):
    """Each body's density and friction coefficients, in the dtype of `params`
    (`mu_kinetic` defaults to `mu_static`)."""
    density = bodies.per_body(density, "density", count)
    mu_static = bodies.per_body(mu_static, "mu_static", count)
    mu_kinetic = (
        mu_static
        if mu_kinetic is None
        else bodies.per_body(mu_kinetic, "mu_kinetic", count)
    )
    dtype = params.density.dtype
    return RigidParams(
        density=jnp.asarray(density, dtype),
        mu_static=jnp.asarray(mu_static, dtype),
        mu_kinetic=jnp.asarray(mu_kinetic, dtype),
    )


def add_elastic_bodies(
    scene: Scene,
    params: Params,
    state: State,
    body,
    *,
    youngs_modulus,
    poisson_ratio,
    density,
    clamped=None,
    substeps: int | None = None,
    courant: float = bodies.ElasticBodies.courant,
    surface_correction: bool = bodies.ElasticBodies.surface_correction,
    friction: bodies.Coulomb | None = None,
    mu_static=None,
    mu_kinetic=None,
    contact: str = "auto",
) -> tuple[Scene, Params, State]:
    """Turn particles of a built case into elastic bodies (seed 000 §2.5.2),
    unstrained as given.

    Args:
        scene, params, state: a case (from `make_scene` etc.), with or without
            rigid bodies (add those first).
        body: body index of each initial particle (or of each slot), -1 for none;
            bodies are numbered 0..b-1. Their free particles become
            `Kind.ELASTIC`.
        youngs_modulus: Young's modulus E [Pa], a scalar or one per body.
        poisson_ratio: Poisson's ratio, in (-1, 0.5), a scalar or one per body.
        density: body density [kg/m^3], a scalar or one per body.
        clamped: which of the bodies' particles are held at their initial
            positions (a boolean per initial particle or per slot, selecting at
            least one; None: none).
            They become `Kind.WALL` for the fluid and keep their place in their
            body's stresses.
        substeps: elastic sub-steps per step; None: the fewest that keep a
            sub-step within `SUBSTEP_MARGIN` (a quarter) of the elastic limit at
            `Params.dt` (`ElasticBodies.time_step_limit`).
        courant, surface_correction: see `jaxmps.bodies.ElasticBodies` (and
            their defaults; surface_correction=False is the seed's model).
        friction: a `jaxmps.bodies.Coulomb` law between the bodies' particles and
            walls (`ElasticBodies.friction_impulse`), or None for frictionless
            contact.
        mu_static, mu_kinetic: the friction coefficients, a scalar or one per
            body (required with `friction`; mu_kinetic defaults to mu_static).
        contact: how the bodies meet walls (`ElasticBodies.contact`):
            "pressure" (through the pressure, as the seed), "push" (a contact
            force in the elastic sub-steps), or "auto": "push" in a scene with
            walls and no fluid, else "pressure" (with nothing to push against
            it costs nothing).

    Returns:
        The new (scene, params, state).

    Raises:
        ValueError: for body indices that are not 0..b-1, bodies on inactive or
            rigid-body slots, clamped particles outside the bodies, a particle
            with no neighbour of its body within r_e, E or density not positive,
            nu outside (-1, 0.5), a `substeps` that leaves `Params.dt` beyond
            the elastic limit, `friction` without `mu_static` (or coefficients
            without `friction`), and a negative coefficient.
    """
    if scene.elastic is not None:
        raise ValueError("This scene already has elastic bodies; add all in one call.")
    active = np.asarray(state.active)
    ids, count = bodies.body_indices(body, scene.capacity, active)
    _refuse_rigid_members(scene, state, ids)
    held = _clamped(clamped, ids, scene.capacity)
    elastic_params = _elastic_params(
        params, count, youngs_modulus, poisson_ratio, density
    )
    elastic_params = _elastic_friction(
        elastic_params, count, friction, mu_static, mu_kinetic
    )
    sub = bodies.elastic_state(
        np.array(state.position, np.float64),
        np.array(state.velocity, np.float64),
        ids,
        held,
        scene.r_e,
        state.position.dtype,
    )
    if substeps is None:
        substeps = _substeps(params, elastic_params, scene.spacing, courant)
    model = bodies.ElasticBodies(
        count=count,
        spacing=scene.spacing,
        first=0 if scene.rigid is None else scene.rigid.count,
        substeps=int(substeps),
        courant=courant,
        surface_correction=bool(surface_correction),
        friction=friction,
        **_surroundings(state, ids, contact),
    )
    new_params = dataclasses.replace(params, elastic=elastic_params)
    new_state = _with_elastic(state, ids, held, sub)
    model.check(new_params, new_state)
    return dataclasses.replace(scene, elastic=model), new_params, new_state


def _refuse_rigid_members(scene: Scene, state: State, ids: np.ndarray) -> None:
    """ValueError where an elastic body takes a rigid body's particles."""
    if scene.rigid is not None and np.any(
        (ids >= 0) & (np.asarray(state.rigid.body) >= 0)
    ):
        raise ValueError("body assigns rigid-body particles to an elastic body.")


def _with_elastic(state: State, ids, held, sub) -> State:
    """`state` with the elastic sub-state `sub`: the bodies' free particles
    `Kind.ELASTIC`, the clamped ones `Kind.WALL` and at rest."""
    kind = np.array(state.kind)
    kind[(ids >= 0) & ~held] = int(Kind.ELASTIC)
    kind[held] = int(Kind.WALL)
    velocity = np.array(state.velocity)
    velocity[held] = 0.0
    return dataclasses.replace(
        state,
        kind=jnp.asarray(kind, state.kind.dtype),
        velocity=jnp.asarray(velocity, state.position.dtype),
        elastic=sub,
    )


def _surroundings(state: State, ids: np.ndarray, contact: str) -> dict:
    """`ElasticBodies.wetted` (fluid particles share the scene) and `contact`,
    "auto" resolved: the push where there are walls outside the bodies and no
    fluid, else the pressure."""
    outside = np.asarray(state.active) & (ids < 0)
    kind = np.asarray(state.kind)
    fluid = np.any(outside & (kind == int(Kind.FLUID)))
    if contact == "auto":
        walls = outside & np.isin(kind, [int(Kind.WALL), int(Kind.DUMMY)])
        contact = "push" if np.any(walls) and not fluid else "pressure"
    return {"wetted": bool(fluid), "contact": contact}


def _elastic_friction(
    elastic: ElasticParams, count: int, friction, mu_static, mu_kinetic
) -> ElasticParams:
    """`elastic` with each body's friction coefficients (ValueError for a
    friction law without mu_static, coefficients without a law, or a negative
    coefficient)."""
    if friction is None:
        if mu_static is not None or mu_kinetic is not None:
            raise ValueError(
                "mu_static / mu_kinetic given without a friction law: pass "
                "friction=jaxmps.bodies.Coulomb() as well (or drop them for "
                "frictionless contact)."
            )
        return elastic
    if mu_static is None:
        raise ValueError(
            "friction needs the static coefficient: give mu_static (a scalar or one "
            "per body; mu_kinetic defaults to it)."
        )
    mu_s = bodies.per_body(mu_static, "mu_static", count)
    mu_k = (
        mu_s if mu_kinetic is None else bodies.per_body(mu_kinetic, "mu_kinetic", count)
    )
    if np.any(mu_s < 0) or np.any(mu_k < 0):
        raise ValueError(
            f"mu_static and mu_kinetic must be >= 0, got {mu_s.tolist()} and "
            f"{mu_k.tolist()}."
        )
    dtype = elastic.density.dtype
    return dataclasses.replace(
        elastic, mu_static=jnp.asarray(mu_s, dtype), mu_kinetic=jnp.asarray(mu_k, dtype)
    )


def _substeps(params: Params, elastic: ElasticParams, spacing: float, courant):
    """The fewest elastic sub-steps per `Params.dt` that keep each within
    `SUBSTEP_MARGIN` of the sub-step limit (`ElasticBodies.limits`)."""
    model = bodies.ElasticBodies(count=1, spacing=spacing, courant=courant)
    values = (elastic.youngs_modulus, elastic.poisson_ratio, elastic.density)
    sub, _ = model.limits(*(np.asarray(v, np.float64) for v in values))
    step_limit = SUBSTEP_MARGIN * float(sub) * spacing
    return max(1, math.ceil(float(params.dt) / step_limit * (1 - 1e-9)))


def _clamped(clamped, ids: np.ndarray, capacity: int) -> np.ndarray:
    """The clamped mask per slot (False beyond the given entries); refuses clamped
    particles that belong to no body."""
    held = np.zeros(capacity, bool)
    if clamped is None:
        return held
    clamped = np.asarray(clamped)
    if clamped.ndim != 1 or clamped.shape[0] > capacity or clamped.dtype != bool:
        raise ValueError(
            f"clamped must be a 1-D boolean array of at most {capacity} entries, got "
            f"shape {clamped.shape} and dtype {clamped.dtype}."
        )
    held[: clamped.shape[0]] = clamped
    if np.any(held & (ids < 0)):
        raise ValueError("clamped marks particles that belong to no elastic body.")
    if not np.any(held):
        raise ValueError(
            "clamped marks no particle: give clamped=None for free bodies, or a mask "
            "that selects the particles to hold."
        )
    return held


def _elastic_params(params: Params, count: int, youngs_modulus, poisson_ratio, density):
    """Each body's E, nu and density in the dtype of `params` (ValueError for E or
    density not positive, nu outside (-1, 0.5))."""
    e = bodies.per_body(youngs_modulus, "youngs_modulus", count)
    nu = bodies.per_body(poisson_ratio, "poisson_ratio", count)
    rho = bodies.per_body(density, "density", count)
    if not np.all((nu > -1) & (nu < 0.5)):
        raise ValueError(
            "poisson_ratio must lie in (-1, 0.5) (at 0.5 the body is incompressible "
            f"and lambda infinite), got {nu.tolist()}."
        )
    dtype = params.density.dtype
    return ElasticParams(
        youngs_modulus=jnp.asarray(e, dtype),
        poisson_ratio=jnp.asarray(nu, dtype),
        density=jnp.asarray(rho, dtype),
    )
