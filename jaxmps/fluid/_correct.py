"""The pressure force: the gradient each particle is corrected with (seed 000 eq.
2.2-8), and for body particles its momentum-conserving form and contact part; the
velocity correction it makes."""

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._coupling import Coupling, FluidLoad
from .._numerics import take_rows
from .._types import (
    PRESSURE_KINDS,
    Field,
    Kind,
    Kinds,
    Mask,
    Scalar,
    Velocities,
    is_kind,
)
from ..operators import AbstractGradient, Discretisation, Pairs


def pressure_gradient(
    gradient: AbstractGradient,
    disc: Discretisation,
    pairs: Pairs,
    pressure: Field,
    kind: Kinds,
    active: Mask,
    select: Bool[Array, "n k"] | None = None,
) -> Float[Array, "n d"]:
    """<grad P>_i over pressure-carrying neighbours.

    # Choice: dummy neighbours are left out of the gradient (and of the corrected
    # gradient's moment matrix), the gradient counterpart of their Neumann treatment
    # in the PPE (p_dummy = p_i contributes nothing).
    """
    carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    include = take_rows(carries, pairs.index)
    return gradient(pairs, pressure, disc, include, select)


def pressure_force(
    gradient: AbstractGradient,
    disc: Discretisation,
    pairs: Pairs,
    pressure: Field,
    kind: Kinds,
    active: Mask,
    coupling: Coupling | None,
) -> FluidLoad:
    """The pressure gradient of every particle at r*, as a `FluidLoad`.

    Fluid particles get the Scene's gradient. Body particles (with a `coupling`)
    get its momentum-conserving form over the pressure-carrying particles outside
    their own body, so that summed over a body the pair forces are exactly those
    across its surface, and the part of it from wall particles (the contact
    reaction) is split out pair by pair.

    # Choice: the corrected gradient is not antisymmetric, so summed over a body
    # its internal pairs leave a spurious net force. Measured on a block resting on
    # a floor: only 49 % of the support came from the pairs with the wall. The
    # symmetric form makes action equal reaction pair by pair.
    """
    carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    include = take_rows(carries, pairs.index)
    applied = gradient(pairs, pressure, disc, include)
    if coupling is None:
        return FluidLoad(
            pairs=pairs, gradient=applied, wall_gradient=jnp.zeros_like(applied)
        )
    owned = jnp.logical_and(active, coupling.owned)
    external = include & ~coupling.internal(pairs)
    wall = take_rows(jnp.logical_and(active, kind == int(Kind.WALL)), pairs.index)
    body_form = gradient.momentum_conserving()
    on_body = body_form(pairs, pressure, disc, external)
    from_walls = body_form(pairs, pressure, disc, external, wall)
    return FluidLoad(
        pairs=pairs,
        gradient=jnp.where(owned[:, None], on_body, applied),
        wall_gradient=jnp.where(owned[:, None], from_walls, 0.0),
    )


def accelerate(
    dt: Scalar,
    gradient: Float[Array, "n d"],
    density: Float[Array, " n"] | Float[Array, ""],
    mobile: Bool[Array, " n"],
) -> Velocities:
    """The pressure correction u' = -dt / rho <grad P> of mobile particles (eq.
    2.2-8), with each particle's own mass density (a body's, or the fluid's)."""
    return jnp.where(
        mobile[:, None], -(dt / jnp.reshape(density, (-1, 1))) * gradient, 0.0
    )
