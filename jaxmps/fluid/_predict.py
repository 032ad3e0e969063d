"""Explicit prediction: viscosity and gravity, the collision guard and the move to
the tentative positions (seed 000 eq. 2.2-3/4)."""

import equinox as eqx
import jax.numpy as jnp

from .._coupling import Coupling
from .._numerics import component_dot, pair_differences, pair_sum, take_rows
from .._params import Params
from .._state import State
from .._types import (
    MOBILE_KINDS,
    Kind,
    Kinds,
    Mask,
    Positions,
    Scalar,
    Velocities,
    is_kind,
)
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

    A fluid particle is also kept off the plane of the wall particles beneath it
    (`wall_plane`): pair distances alone leave holes in a wall, since the middle of
    a lattice cell of a 3-D wall (and of every dummy layer behind it) lies
    l0 / sqrt(2) from its four corners, beyond the 0.5 l0 guard. A thin sheet
    landing on a dry wall carries no pressure (both are free surface), so it fell
    through those holes into the dummies: a tsunami overtopping a quay at l0 = 2
    m. The particle's wall normal n_i is the weighted mean direction from its
    fixed neighbours (walls, dummies) to it; its height h_i is the least of
    (r_i - r_j) . n_i over the fixed neighbours j within the lattice's
    half-diagonal of the line through it along n_i. Where h_i < `distance` l0
    and it approaches (relative to those neighbours' mean velocity), its normal
    velocity is reversed with `restitution`.

    Attributes:
        distance: guard distance, in units of the spacing l0.
        restitution: coefficient of restitution of the exchanged normal momentum.
        wall_plane: also guard fluid particles against the walls' plane.
    """

    distance: float = 0.5
    restitution: float = 0.2
    wall_plane: bool = True

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
        velocity = velocity - pair_sum(impulse, pairs.offset)
        if self.wall_plane:
            velocity = self._off_the_wall(disc, velocity, kind, active, pairs)
        return velocity

    def _off_the_wall(
        self,
        disc: Discretisation,
        velocity: Velocities,
        kind: Kinds,
        active: Mask,
        pairs: Pairs,
    ) -> Velocities:
        """`wall_plane`: fluid particles' approach to the walls' plane."""
        l0 = disc.spacing
        fixed = is_kind(kind, (Kind.WALL, Kind.DUMMY)) & active
        fixed = pairs.valid & take_rows(fixed, pairs.index)
        w = jnp.where(fixed, pairs.weight, 0.0)
        away = -pair_sum(w, pairs.offset)  # from the walls towards i
        square = jnp.sum(away * away, axis=-1)
        # no direction amid walls on both sides (a gap, or deep in a wall): the
        # mean offset is at least a quarter of l0 from one flat wall
        has_normal = square > (0.25 * jnp.sum(w, axis=1) * l0) ** 2
        has_normal = has_normal & (square > 0)
        # (a square root of 0 would have a non-finite derivative)
        size = jnp.sqrt(jnp.where(has_normal, square, 1.0))
        normal = away / size[:, None]
        height = -sum(o * normal[:, c, None] for c, o in enumerate(pairs.offset))
        aside = component_dot(pairs.offset, pairs.offset) - height * height
        half_diagonal = 0.5 * (disc.dim - 1) ** 0.5 * l0
        beneath = fixed & (aside <= (half_diagonal + 0.05 * l0) ** 2)
        lowest = jnp.min(jnp.where(beneath, height, jnp.inf), axis=1)
        count = jnp.maximum(jnp.sum(beneath, axis=1, keepdims=True), 1)
        share = jnp.where(beneath, 1.0 / count, 0.0)
        # relative to the mean velocity of the walls beneath (a moving wall)
        relative = -pair_sum(share, pair_differences(velocity, pairs.index))
        v_n = jnp.sum(relative * normal, axis=-1)
        guard = (
            (kind == int(Kind.FLUID))
            & active
            & has_normal
            & (lowest < self.distance * l0)
            & (v_n < 0)
        )
        kick = jnp.where(guard, -(1.0 + self.restitution) * v_n, 0.0)
        return velocity + kick[:, None] * normal


def advect(
    dt: Scalar, position: Positions, velocity: Velocities, mobile: Mask
) -> Positions:
    """r* = r^k + dt u* for mobile particles (eq. 2.2-4); others stay."""
    return jnp.where(mobile[:, None], position + dt * velocity, position)
