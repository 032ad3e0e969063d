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

    Fluid particles, and body particles marked `coupling.as_fluid`, get the
    Scene's gradient over all their pressure-carrying neighbours, their own body's
    included: the body is pressed exactly like the fluid it replaces (seed 000 §4,
    the passively moving solid), so a body at rest in still water receives the
    buoyancy of the fluid it displaces, whatever the arrangement of the fluid
    particles around it. The other body particles get the momentum-conserving
    (symmetric) pair form over the pressure-carrying particles outside their own
    body, so that the forces between two bodies, and between a body and the walls,
    are equal and opposite pair by pair. For every body particle the part of that
    pair form that wall particles exert (the contact reaction, which the friction
    laws need) is split out pair by pair, and so is the part other bodies exert.

    # Choice: two forms, chosen per body model (`RigidBodies.pressure`), because
    # neither does both jobs. The pair form sums (P_i + P_j) over the pairs across
    # the surface; its terms cancel for a uniform pressure only where the fluid
    # sits on the body's own lattice, so the buoyancy depends on how the fluid
    # particles happen to lie against the body (lifting a box by 0.1 l0 off the
    # lattice in a hydrostatic field cut the force by 23 %), and floating boxes
    # settled 0.3-0.8 l0 too deep (validation/floating_draft.py). The fluid's
    # gradient is consistent, but it is not antisymmetric: between two bodies it
    # breaks momentum conservation, and against walls its wall part is not the
    # reaction it applies, which the friction law's normal force relies on.
    """
    carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    include = take_rows(carries, pairs.index)
    applied = gradient(pairs, pressure, disc, include)
    if coupling is None:
        return FluidLoad(
            pairs=pairs,
            gradient=applied,
            wall_gradient=jnp.zeros_like(applied),
            body_gradient=jnp.zeros_like(applied),
        )
    owned = jnp.logical_and(active, coupling.owned)
    external = include & ~coupling.internal(pairs)
    if coupling.apart is not None:  # a model's own wall contact
        external = external & ~coupling.detached(pairs)
    wall = take_rows(jnp.logical_and(active, kind == int(Kind.WALL)), pairs.index)
    body_form = gradient.momentum_conserving()
    on_body = body_form(pairs, pressure, disc, external)
    from_walls = body_form(pairs, pressure, disc, external, wall)
    between = None
    if coupling.between_bodies:
        from_bodies = body_form(
            pairs, pressure, disc, external, take_rows(owned, pairs.index)
        )
        between = jnp.where(owned[:, None], from_bodies, 0.0)
    paired = owned & ~coupling.as_fluid
    return FluidLoad(
        pairs=pairs,
        gradient=jnp.where(paired[:, None], on_body, applied),
        wall_gradient=jnp.where(owned[:, None], from_walls, 0.0),
        body_gradient=between,
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
