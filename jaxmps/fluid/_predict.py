"""Explicit prediction: viscosity, gravity, collision guard (seed 000 eq. 2.2-3/4)."""

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .. import neighbours
from .._numerics import component_dot, pair_differences, pair_sum, take_rows
from .._params import Params
from .._types import MOBILE_KINDS, is_kind
from ..bodies import particle_density, without_internal_pairs
from ..operators import Pairs, make_pairs


def predict_velocity(
    scene,
    params: Params,
    velocity: Float[Array, "n d"],
    kind,
    active,
    pairs: Pairs,
    density=None,
) -> Float[Array, "n d"]:
    """u* = u^k + dt (nu <lap u>^k + g) for mobile particles (eq. 2.2-3).

    Walls and dummies enter the Laplacian with their own (prescribed) velocity, which
    makes walls no-slip for the viscous term. # Choice: the seed says free-slip but does
    not say how; standard MPS includes wall particles in the viscous Laplacian.

    With `density` (per particle; bodies heavier or lighter than the fluid) the
    viscous force rho0 nu <lap u> acts on a particle of mass density rho_i, so its
    acceleration is (rho0 / rho_i) nu <lap u>: the pair forces then stay equal and
    opposite between a body and the fluid.
    """
    lap_u = scene.laplacian(pairs, velocity, scene)
    viscous = params.viscosity * lap_u
    if density is not None:
        viscous = viscous * jnp.reshape(params.density / density, (-1, 1))
    accel = viscous + params.gravity[None, :]
    mobile = jnp.logical_and(active, is_kind(kind, MOBILE_KINDS))
    return jnp.where(mobile[:, None], velocity + params.dt * accel, velocity)


def predict_state_velocity(scene, params: Params, state, pairs: Pairs):
    """`predict_velocity` for a State: in scenes with rigid bodies, pairs inside one
    body carry no viscosity and body particles use their own density."""
    if state.rigid is None:
        return predict_velocity(
            scene, params, state.velocity, state.kind, state.active, pairs
        )
    return predict_velocity(
        scene,
        params,
        state.velocity,
        state.kind,
        state.active,
        without_internal_pairs(state, pairs),
        particle_density(params, state),
    )


def collide(
    velocity: Float[Array, "n d"],
    kind,
    active: Bool[Array, " n"],
    pairs: Pairs,
    distance: float,
    restitution: float,
) -> Float[Array, "n d"]:
    """Collision guard: pairs closer than `distance` that approach each other exchange
    normal momentum with coefficient of restitution `restitution`.

    # Choice: the seed names no collision model; this is the usual MPS guard
    # (Koshizuka; Lee et al. 2011) against particle clustering. It acts on the
    # predicted velocity u* with the pair geometry at step k (one Jacobi sweep), so it
    # needs no extra neighbour search. Mobile-mobile pairs share the impulse equally
    # (momentum conserving); a fixed partner (wall, dummy) takes none of it.
    """
    mobile = jnp.logical_and(active, is_kind(kind, MOBILE_KINDS))
    inverse_r = 1.0 / pairs.distance
    # > 0: approaching
    v_n = -component_dot(pair_differences(velocity, pairs.index), pairs.offset)
    v_n = v_n * inverse_r
    close = pairs.valid & (pairs.distance < distance) & (v_n > 0) & mobile[:, None]
    partner_mobile = take_rows(mobile, pairs.index)
    share = jnp.where(partner_mobile, 0.5, 1.0)
    impulse = jnp.where(close, (1.0 + restitution) * share * v_n * inverse_r, 0.0)
    return velocity - pair_sum(impulse, pairs.offset)


def is_mobile(kind, active) -> Bool[Array, " n"]:
    return jnp.logical_and(active, is_kind(kind, MOBILE_KINDS))


def neighbour_pairs(
    scene,
    position: Float[Array, "n d"],
    active: Bool[Array, " n"],
    cache: neighbours.NeighbourCache | None = None,
):
    """Neighbour lists at `position` and their pair geometry: (Neighbours, Pairs).

    The lists are searched within r_e + `scene.neighbour_skin`, so that they can be
    carried to the next step (`neighbours.NeighbourCache`); with `cache`, its lists
    are used instead of a search while they still hold every pair closer than r_e.
    Pairs beyond r_e are masked by the pair geometry (`Pairs.valid`).
    """
    skin = scene.neighbour_skin
    if cache is None:
        nbrs = neighbours.build(
            scene.grid, position, active, scene.max_neighbours, scene.r_e + skin
        )
    else:
        nbrs = neighbours.reuse_or_build(
            scene.grid, position, active, scene.max_neighbours, scene.r_e, skin, cache
        )
    return nbrs, make_pairs(nbrs.index, position, scene.weight, scene.r_e)


def carry_neighbours(state, nbrs, position):
    """The cache the next step receives: `nbrs` (built at `position`) when the
    state carries one, else None."""
    if state.neighbours is None:
        return None
    return neighbours.NeighbourCache.of(nbrs, position, state.active)
