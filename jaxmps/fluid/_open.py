"""Open boundaries on the fixed-capacity pool: inflow (Aida 2014; seed 000 §2.11,
seed 002 §2.8) and outflow. Particles are activated and deactivated, never
allocated: the State's shapes never change."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._params import InflowParams
from .._state import State
from .._types import Kind
from ..neighbours import Grid
from ..operators import Discretisation


class Inflow(eqx.Module):
    """A moving inflow boundary at the upstream (low-x) end.

    Boundary particles (a pressure-wall layer facing the fluid plus dummy layers
    behind it) move along +x at the inflow velocity. Each time the pressure layer has
    travelled one spacing from `origin`, a column of fluid particles is activated from
    the inactive pool at the pressure-layer positions and the boundary steps back by
    l0. The spawned column height is fixed by the pressure layer (Aida's option (i):
    a prescribed number of particles, which also feeds a dry bed).

    Attributes:
        pressure_layer: indices of the pressure-layer boundary particles.
        boundary: indices of all boundary particles (pressure + dummy layers).
        origin: initial x of the pressure layer [m].
    """

    pressure_layer: tuple[int, ...]
    boundary: tuple[int, ...]
    origin: float


class Outflow(eqx.Module):
    """Fluid particles beyond `position` along `axis` leave the simulation: they are
    deactivated (returned to the pool) and parked at the domain origin."""

    position: float
    axis: int = 0


def apply_inflow(
    disc: Discretisation,
    inflow: Inflow,
    params: InflowParams,
    dt: Float[Array, ""],
    state: State,
) -> tuple[State, Bool[Array, ""]]:
    """Move the inflow boundary and spawn a fluid column when it has moved l0.

    Returns the new state and whether the pool was too small for a spawn (the spawn
    is then partial; `Result.pool_exhausted` is set by the step).
    Discrete decision: when a column spawns carries no gradient; the spawned
    particles' positions and velocities do (through the inflow velocity).
    """
    n = state.position.shape[0]
    layer = jnp.asarray(inflow.pressure_layer)
    boundary = jnp.asarray(inflow.boundary)
    u = params.velocity
    e_x = jnp.zeros(disc.dim, state.position.dtype).at[0].set(1.0)
    position = state.position.at[boundary, 0].add(u * dt)
    velocity = state.velocity.at[boundary].set(u * e_x)
    spawn = position[layer[0], 0] - inflow.origin >= disc.spacing
    free = jnp.nonzero(~state.active, size=layer.shape[0], fill_value=n)[0]
    short = spawn & jnp.any(free == n)
    target = jnp.where(spawn, free, n)
    position = position.at[target].set(position[layer], mode="drop")
    velocity = velocity.at[target].set(u * e_x, mode="drop")
    kind = state.kind.at[target].set(int(Kind.FLUID), mode="drop")
    active = state.active.at[target].set(True, mode="drop")
    pressure = state.pressure.at[target].set(0.0, mode="drop")
    position = position.at[boundary, 0].add(jnp.where(spawn, -disc.spacing, 0.0))
    new = eqx.tree_at(
        lambda s: (s.position, s.velocity, s.kind, s.active, s.pressure),
        state,
        (position, velocity, kind, active, pressure),
    )
    return new, short


def apply_outflow(outflow: Outflow, grid: Grid, state: State) -> State:
    """Deactivate fluid particles past the outflow plane."""
    gone = (
        state.active
        & (state.kind == int(Kind.FLUID))
        & (state.position[:, outflow.axis] > outflow.position)
    )
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
