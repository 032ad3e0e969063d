"""Host-side construction of Scene, Params and State (NumPy; validates its inputs)."""

import math

import jax.numpy as jnp
import numpy as np

from ._params import Params
from ._result import Result
from ._scene import Scene
from ._state import State
from .fluid import AbstractSolver, SemiImplicit
from .neighbours import Grid
from .operators import (
    AbstractGradient,
    AbstractWeight,
    CorrectedGradient,
    MPSWeight,
    lattice_offsets,
    reference_constants,
)


def make_scene(
    position,
    spacing: float,
    domain: tuple,
    *,
    capacity: int | None = None,
    r_e: float = 2.1,
    weight: AbstractWeight = MPSWeight(),
    gradient: AbstractGradient = CorrectedGradient(minimum_shift=True),
    solver: AbstractSolver = SemiImplicit(),
    neighbour_margin: float = 2.0,
    cell_margin: float = 1.5,
    max_neighbours: int | None = None,
    cell_capacity: int | None = None,
    courant_limit: float = 0.5,
) -> Scene:
    """Build a Scene for the initial particle positions.

    Args:
        position: initial positions of the active particles, shape (m, d).
        spacing: lattice spacing l0 [m].
        domain: (lower, upper) corners of the domain box [m]; particles leaving it
            set `Result.left_domain`.
        capacity: particle slots (>= m); the extra slots form the inactive pool.
        r_e: influence radius in units of l0 (2.1 in seed 000).
        neighbour_margin: `max_neighbours` = ceil(margin x lattice neighbour count).
        cell_margin: `cell_capacity` = ceil(margin x the fullest cell initially).
        max_neighbours, cell_capacity: explicit values override the margins.

    Returns:
        The Scene, with n0 and lambda of the regular lattice (DESIGN.md §7).
    """
    position = np.asarray(position, dtype=np.float64)
    if position.ndim != 2 or position.shape[1] not in (2, 3):
        raise ValueError(f"position must have shape (m, 2|3), got {position.shape}.")
    m, dim = position.shape
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
    shape = tuple(int(s) for s in np.maximum(np.ceil((upper - lower) / radius), 1))
    if cell_capacity is None:
        coords = np.clip(np.floor((position - lower) / radius).astype(int), 0, None)
        _, counts = np.unique(coords, axis=0, return_counts=True)
        fullest = int(counts.max()) if m else 1
        cell_capacity = max(2, math.ceil(cell_margin * fullest))
    if max_neighbours is None:
        lattice_count = len(lattice_offsets(dim, r_e))
        max_neighbours = math.ceil(neighbour_margin * lattice_count)
    grid = Grid(
        origin=tuple(float(v) for v in lower),
        cell_size=radius,
        shape=shape,
        cell_capacity=int(cell_capacity),
    )
    return Scene(
        dim=dim,
        capacity=capacity,
        spacing=float(spacing),
        r_e=float(radius),
        n0=n0,
        lam=lam * spacing**2,
        grid=grid,
        max_neighbours=int(max_neighbours),
        courant_limit=float(courant_limit),
        weight=weight,
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
