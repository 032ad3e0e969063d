"""Explicit prediction: viscosity and gravity, the collision guard and the move to
the tentative positions (seed 000 eq. 2.2-3/4)."""

import equinox as eqx
import jax.numpy as jnp

from .._coupling import Coupling
from .._numerics import component_dot, pair_differences, pair_sum, take_rows
from .._params import Params
from .._state import State
from .._types import MOBILE_KINDS, Kinds, Mask, Positions, Scalar, Velocities, is_kind
from ..operators import AbstractLaplacian, Discretisation, Pairs


def is_mobile(kind: Kinds, active: Mask) -> Mask:
    """Active particles advanced by the fluid equations (fluid and body particles)."""
    return jnp.logical_and(active, is_kind(kind, MOBILE_KINDS))


def predict(
    disc: Discretisation,
    laplacian: AbstractLaplacian,
    params: Params,
    state: State,
    pairs: Pairs,
    coupling: Coupling | None,
) -> Velocities:
    """u* = u^k + dt (nu <lap u>^k + g) for mobile particles (eq. 2.2-3).

    Walls and dummies enter the Laplacian with their own (prescribed) velocity, which
    makes walls no-slip for the viscous term. # Choice: the seed says free-slip but does
    not say how; standard MPS includes wall particles in the viscous Laplacian.

    With a `coupling` (scenes with bodies), pairs inside one body carry no viscosity,
    and the viscous force rho0 nu <lap u> acts on a particle of mass density rho_i,
    so its acceleration is (rho0 / rho_i) nu <lap u>: the pair forces then stay
    equal and opposite between a body and the fluid. A body model's outside force
    per unit volume (`Coupling.force`) accelerates a particle by force / rho_i.
    """
    velocity = state.velocity
    if coupling is not None:
        pairs = coupling.without_internal(pairs)
    viscous = params.viscosity * laplacian(pairs, velocity, disc)
    if coupling is not None:
        viscous = viscous * jnp.reshape(params.density / coupling.density, (-1, 1))
    accel = viscous + params.gravity[None, :]
    if coupling is not None and coupling.force is not None:
        accel = accel + coupling.force / coupling.density[:, None]
    mobile = is_mobile(state.kind, state.active)
    return jnp.where(mobile[:, None], velocity + params.dt * accel, velocity)


class CollisionGuard(eqx.Module):
    """Pairs closer than `distance` that approach each other exchange normal
    momentum with coefficient of restitution `restitution`.

    # Choice: the seeds name no collision model; this is the usual MPS guard
    # (Koshizuka; Lee et al. 2011) against particle clustering. It acts on the
    # predicted velocity u* with the pair geometry at step k (one Jacobi sweep), so it
    # needs no extra neighbour search. Mobile-mobile pairs share the impulse equally
    # (momentum conserving); a fixed partner (wall, dummy) takes none of it.

    Attributes:
        distance: guard distance, in units of the spacing l0.
        restitution: coefficient of restitution of the exchanged normal momentum.
    """

    distance: float = 0.5
    restitution: float = 0.2

    def __check_init__(self):
        if not self.distance > 0:
            raise ValueError(
                f"CollisionGuard.distance must be positive, got {self.distance}."
            )
        if not 0 <= self.restitution <= 1:
            raise ValueError(
                "CollisionGuard.restitution must lie in [0, 1], got "
                f"{self.restitution}."
            )

    def __call__(
        self,
        disc: Discretisation,
        velocity: Velocities,
        kind: Kinds,
        active: Mask,
        pairs: Pairs,
    ) -> Velocities:
        """The velocities after the guard."""
        mobile = is_mobile(kind, active)
        inverse_r = 1.0 / pairs.distance
        # > 0: approaching
        v_n = -component_dot(pair_differences(velocity, pairs.index), pairs.offset)
        v_n = v_n * inverse_r
        limit = self.distance * disc.spacing
        close = pairs.valid & (pairs.distance < limit) & (v_n > 0) & mobile[:, None]
        partner_mobile = take_rows(mobile, pairs.index)
        share = jnp.where(partner_mobile, 0.5, 1.0)
        impulse = jnp.where(
            close, (1.0 + self.restitution) * share * v_n * inverse_r, 0.0
        )
        return velocity - pair_sum(impulse, pairs.offset)


def advect(
    dt: Scalar, position: Positions, velocity: Velocities, mobile: Mask
) -> Positions:
    """r* = r^k + dt u* for mobile particles (eq. 2.2-4); others stay."""
    return jnp.where(mobile[:, None], position + dt * velocity, position)
