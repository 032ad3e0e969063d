"""Open boundaries on the fixed-capacity pool: inflow (Aida 2014; seed 000 §2.11,
seed 002 §2.8) and outflow. Particles are activated and deactivated, never
allocated: the State's shapes never change."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._params import InflowParams
from .._state import State
from .._types import Kind
from ..geometry import block
from ..neighbours import Grid
from ..operators import Discretisation


class Inflow(eqx.Module):
    """A moving inflow boundary at one end of the domain, facing the fluid along
    `direction` x e_axis (in 2-D and 3-D).

    Boundary particles (a pressure-wall layer facing the fluid plus dummy layers
    behind it) move along the inflow direction at the inflow velocity. Each time the
    pressure layer has travelled one spacing from `origin`, a column (a sheet, in
    3-D) of fluid particles is activated from the inactive pool at the
    pressure-layer positions below the prescribed depth, and the boundary steps
    back by l0 (Aida 2014, option (i): a prescribed number of particles, which
    reproduces a prescribed surface elevation and also feeds a dry bed). When the
    velocity is negative and the boundary has retreated one spacing, the fluid
    within one spacing in front of it is returned to the pool and the boundary
    steps forward by l0 (Aida's outflow rule).

    An `absorbing` boundary lets a wave reflected back to it leave the domain
    (the sea beyond it is open) instead of reflecting again as a piston would:
    it imposes the incoming shallow-water characteristic u + 2 sqrt(g d) of the
    prescribed series (u_I, d_I) and reads the depth d in front of it, moving at
    u = u_I + 2 (sqrt(g d_I) - sqrt(g d)): the prescribed speed while the water
    in front is as deep as prescribed, slower (or backwards, withdrawing water)
    where a reflection has raised it. Needs a prescribed depth. It reads the
    depth over the three columns in front and compares it with what it fed
    into them (`_absorption`): compared with the depth it feeds now it fed a
    rising wave 0.75-1.4 columns too much (a fixed offset made while the depth
    rises); with the bookkeeping it feeds as the piston does, within a third of
    a column.

    Attributes:
        pressure_layer: indices of the pressure-layer boundary particles.
        boundary: indices of all boundary particles (pressure + dummy layers).
        origin: initial coordinate of the pressure layer along `axis` [m].
        axis: the axis the boundary moves along (0 = x).
        direction: +1 when the fluid lies on the boundary's +axis side, -1 when it
            lies on the -axis side (an inflow at the high end).
        absorbing: the boundary absorbs waves reflected back to it (above).
        across: the pressure layer's lattice columns across the flow (1 in 2-D):
            the depth in front is the fluid's volume there over their area.
    """

    pressure_layer: tuple[int, ...]
    boundary: tuple[int, ...]
    origin: float
    axis: int = 0
    direction: int = 1
    absorbing: bool = False
    across: int = 1

    def __check_init__(self):
        if self.direction not in (1, -1):
            raise ValueError(
                f"Inflow.direction must be +1 or -1, got {self.direction}."
            )


class Outflow(eqx.Module):
    """Fluid particles beyond `position` along `direction` x e_axis leave the
    simulation: they are deactivated (returned to the pool) and parked at the domain
    origin. DEM grains beyond it leave too (`apply_outflow`)."""

    position: float
    axis: int = 0
    direction: int = 1

    def __check_init__(self):
        if self.direction not in (1, -1):
            raise ValueError(
                f"Outflow.direction must be +1 or -1, got {self.direction}."
            )


def inflow_boundary(
    face: float,
    lower,
    upper,
    spacing: float,
    *,
    axis: int = 0,
    direction: int = 1,
    layers: int = 3,
    first: int = 0,
    absorbing: bool = False,
) -> tuple[np.ndarray, np.ndarray, Inflow]:
    """The particles of an inflow boundary whose fluid starts at `face` along
    `axis` and lies on its `direction` side, across the box [`lower`, `upper`] of
    the other axes (the entries at `axis` are ignored): a pressure layer l0/2
    behind the face and `layers` - 1 dummy layers behind it, on the lattice of
    spacing l0. `first` is the index the first of them will have in the state;
    `absorbing` makes it let reflected waves out (`Inflow`).

    Returns:
        positions (m, d), kinds (m,) (`Kind.WALL`, then `Kind.DUMMY`) and the
        `Inflow` that moves them.
    """
    lower = np.array(lower, dtype=np.float64)
    upper = np.array(upper, dtype=np.float64)
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}.")
    if layers < 1:
        raise ValueError(f"layers must be at least 1, got {layers}.")
    lower[axis], upper[axis] = 0.0, spacing
    sheet = block(lower, upper, spacing)
    sheet[:, axis] = 0.0
    offsets = -direction * (np.arange(layers) + 0.5) * spacing
    points = np.concatenate(
        [sheet + (face + o) * np.eye(len(lower))[axis] for o in offsets]
    )
    kinds = np.where(np.arange(len(points)) < len(sheet), Kind.WALL, Kind.DUMMY)
    lateral = [k for k in range(len(lower)) if k not in (axis, len(lower) - 1)]
    columns = np.unique(np.round(sheet[:, lateral] / spacing), axis=0)
    inflow = Inflow(
        pressure_layer=tuple(range(first, first + len(sheet))),
        boundary=tuple(range(first, first + len(points))),
        origin=float(face + offsets[0]),
        axis=axis,
        direction=direction,
        absorbing=absorbing,
        across=len(columns) if lateral else 1,
    )
    return points, kinds.astype(np.int32), inflow


def apply_inflow(
    disc: Discretisation,
    inflow: Inflow,
    params: InflowParams,
    grid: Grid,
    dt: Float[Array, ""],
    state: State,
    gravity: Float[Array, ""] | None = None,
) -> tuple[State, Bool[Array, ""]]:
    """Move the inflow boundary over [t, t + dt] and spawn a fluid column when it
    has advanced l0 (or withdraw one when it has retreated l0). `gravity` [m/s^2]
    is needed by an absorbing boundary.

    Returns the new state and whether the pool was too small for a spawn (the spawn
    is then partial; `Result.pool_exhausted` is set by the step).
    Discrete decision: when a column spawns carries no gradient; the spawned
    particles' positions and velocities do (through the inflow velocity).
    """
    axis, sign, l0 = inflow.axis, inflow.direction, disc.spacing
    layer = jnp.asarray(inflow.pressure_layer)
    boundary = jnp.asarray(inflow.boundary)
    u_start, _ = params.at(state.time)
    u_end, depth = params.at(state.time + dt)
    # The trapezoid of the velocity over the step: a tabulated series is followed
    # exactly (piecewise linear), the boundary carries the step's mean velocity.
    shift = 0.5 * (u_start + u_end) * dt
    if inflow.absorbing:
        if depth is None or gravity is None:
            raise ValueError(
                "An absorbing inflow needs a prescribed depth "
                "(InflowParams.depth) and gravity."
            )
        absorb = _absorption(inflow, params, l0, gravity, state)
        shift = shift + absorb * dt
        u_end = u_end + absorb
    e = jnp.zeros(disc.dim, state.position.dtype).at[axis].set(sign)
    position = state.position.at[boundary, axis].add(sign * shift)
    velocity = state.velocity.at[boundary].set((shift / dt) * e)
    travel = sign * (position[layer[0], axis] - inflow.origin)
    state = eqx.tree_at(lambda s: (s.position, s.velocity), state, (position, velocity))
    state, short = _spawn(inflow, depth, l0, u_end * e, travel >= l0, state)
    state = _withdraw(inflow, grid, l0, travel <= -l0, state)
    return state, short


def _absorption(inflow: Inflow, params: InflowParams, l0: float, gravity, state):
    """The absorbing boundary's correction to the prescribed speed [m/s],
    2 (sqrt(g d_I) - sqrt(g d)): d the fluid's volume within three spacings in
    front of the pressure layer over that strip's area, and d_I what the
    boundary fed into that strip when nothing comes back: the mean of the
    three columns it spawned there (whole particles under the prescribed depth,
    as `_spawn` counts them), the newest one l0 ahead and spawned when the
    boundary was last stepped back, a fraction phi = travel / l0 of a spacing
    ago, the others one and two spacings before it, each read from the series
    (k + phi) l0 / u_I earlier. Still water as deep as prescribed, and a wave
    exactly as prescribed, read no correction. A count: no gradient."""
    axis, sign = inflow.axis, inflow.direction
    layer = jnp.asarray(inflow.pressure_layer)
    at_layer = state.position[layer]
    up = at_layer.shape[1] - 1
    bottom = jnp.min(at_layer[:, up]) - 0.5 * l0
    u_now, _ = params.at(state.time)
    phi = jnp.clip(sign * (at_layer[0, axis] - inflow.origin) / l0, 0.0, 1.0)
    step_time = l0 / jnp.maximum(jnp.abs(u_now), 1e-12)
    spawned = jnp.stack(
        [params.at(state.time - (k + phi) * step_time)[1] for k in range(3)]
    )
    below = at_layer[:, up][None, :] - bottom < spawned[:, None]
    fed = jnp.mean(jnp.sum(below, axis=1)) * l0 / inflow.across
    ahead = sign * (state.position[:, axis] - at_layer[0, axis])
    inside = state.active & (state.kind == int(Kind.FLUID))
    inside &= (ahead > 0.5 * l0) & (ahead <= 3.5 * l0)
    for k in range(at_layer.shape[1]):
        if k in (axis, up):
            continue
        low = jnp.min(at_layer[:, k]) - 0.5 * l0
        high = jnp.max(at_layer[:, k]) + 0.5 * l0
        inside &= (state.position[:, k] >= low) & (state.position[:, k] < high)
    front = jnp.sum(inside) * l0 / (3 * inflow.across)
    g = jax.lax.stop_gradient(jnp.asarray(gravity, state.position.dtype))
    return jax.lax.stop_gradient(2.0 * (jnp.sqrt(g * fed) - jnp.sqrt(g * front)))


def _spawn(inflow: Inflow, depth, l0: float, velocity, spawn, state: State):
    """Activate pool slots at the pressure layer's positions below `depth` (all of
    them when None) when `spawn`, then step the boundary back by l0. Returns the
    state and whether the pool ran short."""
    n = state.position.shape[0]
    layer = jnp.asarray(inflow.pressure_layer)
    boundary = jnp.asarray(inflow.boundary)
    at_layer = state.position[layer]
    up = at_layer.shape[1] - 1
    if depth is None:
        fed = jnp.ones(layer.shape[0], bool)
    else:
        bottom = jnp.min(at_layer[:, up]) - 0.5 * l0
        fed = at_layer[:, up] - bottom < depth
    # The pool: inactive slots that are not grains' (a grain carried out keeps
    # its slot in the grains' index).
    spare = ~state.active & (state.kind != int(Kind.SEDIMENT))
    free = jnp.nonzero(spare, size=layer.shape[0], fill_value=n)[0]
    slot = free[jnp.clip(jnp.cumsum(fed) - 1, 0, layer.shape[0] - 1)]
    short = spawn & jnp.any(fed & (slot == n))
    target = jnp.where(spawn & fed, slot, n)
    position = state.position.at[target].set(at_layer, mode="drop")
    position = position.at[boundary, inflow.axis].add(
        jnp.where(spawn, -inflow.direction * l0, 0.0)
    )
    new = eqx.tree_at(
        lambda s: (s.position, s.velocity, s.kind, s.active, s.pressure),
        state,
        (
            position,
            state.velocity.at[target].set(velocity, mode="drop"),
            state.kind.at[target].set(int(Kind.FLUID), mode="drop"),
            state.active.at[target].set(True, mode="drop"),
            state.pressure.at[target].set(0.0, mode="drop"),
        ),
    )
    return new, short


def _withdraw(inflow: Inflow, grid: Grid, l0: float, withdraw, state: State):
    """When `withdraw`, return the fluid within one spacing in front of the
    pressure layer's original place (and any behind it, over the layer's
    cross-section) to the pool, and step the boundary forward by l0."""
    axis, sign = inflow.axis, inflow.direction
    layer = jnp.asarray(inflow.pressure_layer)
    at_layer = state.position[layer]
    across = [k for k in range(at_layer.shape[1]) if k != axis]
    inside = jnp.ones(state.position.shape[0], bool)
    for k in across:
        low = jnp.min(at_layer[:, k]) - 0.5 * l0
        high = jnp.max(at_layer[:, k]) + 0.5 * l0
        inside &= (state.position[:, k] >= low) & (state.position[:, k] < high)
    ahead = sign * (state.position[:, axis] - inflow.origin)
    gone = (
        withdraw
        & state.active
        & (state.kind == int(Kind.FLUID))
        & inside
        & (ahead < 0.5 * l0)
    )
    state = retire(gone, grid, state)
    boundary = jnp.asarray(inflow.boundary)
    position = state.position.at[boundary, axis].add(
        jnp.where(withdraw, sign * l0, 0.0)
    )
    return eqx.tree_at(lambda s: s.position, state, position)


def apply_outflow(outflow: Outflow, grid: Grid, state: State) -> State:
    """Deactivate fluid particles and DEM grains past the outflow plane (sediment
    carried out of a flume leaves it, as over seed 002's free overfall). A
    grain's slot stays a grain's (`Kind.SEDIMENT`, never refilled by an inflow),
    parked and inactive."""
    past = outflow.direction * (state.position[:, outflow.axis] - outflow.position)
    carried = (state.kind == int(Kind.FLUID)) | (state.kind == int(Kind.SEDIMENT))
    return retire(state.active & carried & (past > 0), grid, state)


def retire(gone, grid: Grid, state: State) -> State:
    """Return the `gone` particles to the pool, parked at the domain origin."""
    origin = jnp.asarray(grid.origin, state.position.dtype)[None, :]
    return eqx.tree_at(
        lambda s: (s.position, s.velocity, s.pressure, s.active),
        state,
        (
            jnp.where(gone[:, None], origin, state.position),
            jnp.where(gone[:, None], 0.0, state.velocity),
            jnp.where(gone, 0.0, state.pressure),
            state.active & ~gone,
        ),
    )
