"""The two records that pass between the fluid stages and the body stages of a step.

Bodies → fluid (`Coupling`, built before the fluid stages): the mass density each
particle is advanced with, and which particles belong to one body, so that the fluid
exerts no viscous or pressure force between two particles of the same body (its
internal forces are the body model's business) and gives body particles the
momentum-conserving form of the pressure gradient; and, for a deformable body, the
number density its particles have in the unstrained body, so that the pressure's
source (incompressibility) sees the body as rigid within itself and the body's
own strain is left to its own stresses.

Fluid → bodies (`FluidLoad`, built by the pressure-force stage): the pair geometry
the pressure acted on, the pressure gradient applied to every particle, and the part
of it that wall particles exerted on body particles (the contact reaction, which the
friction laws need).

Neither side reads or writes the other's state: a new body model (elastic bodies,
grains) contributes its part of a `Coupling` and reads a `FluidLoad`.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from ._numerics import take_rows
from .operators import Pairs, number_density


class Coupling(eqx.Module):
    """What the body models impose on the fluid stages of one step.

    Attributes:
        density: mass density each particle is advanced with [kg/m^3]: its body's
            density for body particles, the fluid density elsewhere, shape (n,).
        owner: the body each particle belongs to, -1 for none, shape (n,). Owners
            are unique across body models (each model numbers its bodies from its
            own offset).
        as_fluid: body particles whose pressure force is the fluid's own gradient
            over all their neighbours, their own body's included (the body is
            pressed like the fluid it replaces); elsewhere on a body, the pair form
            across its surface (see `fluid.pressure_force`), shape (n,).
        reference_density: for particles of a deformable body, the number
            density their own body gives them unstrained (its pairs at their
            reference distances); -1 elsewhere; None: no deformable body. The
            pressure stage's source counts these in place of the body's pairs as
            they are (`source_view`), shape (n,).
        hidden: particles the fluid does not see (DEM grains, which feel the
            fluid through drag and lift alone and act on it through nothing):
            every pair with one of them weighs nothing in the fluid stages
            (`visible`); None: none, shape (n,).
        packing: the weight a particle's pairs carry in the fluid's sums, 1 on
            the lattice and n0 / n_s0 for grains packed in a bed (seed 002 eq.
            3.73: the junction of lattice walls and a packed bed), applied to
            the pairs whose partner it is (`visible`); None: 1 everywhere,
            shape (n,).
        pores: the weight of a fluid particle in a porous region of porosity
            phi < 1 (`fluid.pore_weight`), which stands sparser there: a pair
            weighs the geometric mean of its two particles' (symmetric, so that
            the pressure equation stays symmetric; along a smooth porosity it
            sums as the partner's weight would, to first order); None: 1
            everywhere, shape (n,).
        force: a force per unit volume [N/m^3] the body models exert on
            particles from outside the fluid stages (the DEM grains' contacts on
            body particles and their drag on the fluid, from the last step),
            added to the prediction of mobile particles as dt force / density;
            None: none, shape (n, d).
        apart: 1 for body particles whose contact with walls is the body
            model's own (`ElasticBodies.contact = "push"`), 2 for the walls and
            dummies they may touch, 0 elsewhere: the pressure leaves the pairs
            of a 1 and a 2 out of its source and its force (`detached`); None:
            none, shape (n,).
        between_bodies: whether the pressure stage splits out the part of the
            pair form that other bodies exert (`FluidLoad.body_gradient`, which
            friction between bodies needs); static.
        pressed: whether any body is pressed like the fluid (`as_fluid` can be
            True somewhere), so that a scene without one compiles nothing for
            them; static.
    """

    density: Float[Array, " n"]
    owner: Int[Array, " n"]
    as_fluid: Bool[Array, " n"]
    reference_density: Float[Array, " n"] | None = None
    hidden: Bool[Array, " n"] | None = None
    packing: Float[Array, " n"] | None = None
    pores: Float[Array, " n"] | None = None
    force: Float[Array, "n d"] | None = None
    apart: Int[Array, " n"] | None = None
    between_bodies: bool = eqx.field(static=True, default=False)
    pressed: bool = eqx.field(static=True, default=False)

    @property
    def owned(self) -> Bool[Array, " n"]:
        """Particles that belong to a body."""
        return self.owner >= 0

    def internal(self, pairs: Pairs) -> Bool[Array, "n k"]:
        """Pairs (i, j) of two particles of one body."""
        partner = take_rows(self.owner + 1, pairs.index) - 1  # sentinel reads -1
        return (self.owner[:, None] >= 0) & (partner == self.owner[:, None])

    def detached(self, pairs: Pairs) -> Bool[Array, "n k"]:
        """Pairs (i, j) of a body particle that makes its own wall contact and a
        wall (`apart`), either way round; all False without such bodies."""
        if self.apart is None:
            return jnp.zeros(pairs.index.shape, bool)
        partner = take_rows(self.apart, pairs.index)
        own = self.apart[:, None]
        return ((own == 1) & (partner == 2)) | ((own == 2) & (partner == 1))

    def without_internal(self, pairs: Pairs) -> Pairs:
        """`pairs` with zero weight between two particles of one body (for the
        viscous term: a rigid body has no internal viscosity, and the pairwise MPS
        Laplacian of a rigid rotation is not zero at its surface, so left in it
        would brake a spinning body with a spurious internal torque)."""
        weight = jnp.where(self.internal(pairs), 0.0, pairs.weight)
        return eqx.tree_at(lambda p: p.weight, pairs, weight)

    def source_view(self, pairs: Pairs) -> tuple[Pairs, Float[Array, " n"]]:
        """The pairs and number density the pressure's source sees: a deformable
        body's particles see each other at their reference distances (their pairs
        weigh 0 and their unstrained number density is added), so that the
        incompressibility condition holds the body's surface against what is
        outside it and not against the body's own strain, which its stresses
        govern. A rigid body is unchanged by this (its pairs keep their reference
        distances and its internal relative velocities are normal to them)."""
        if self.reference_density is None:
            return pairs, number_density(pairs)
        held = self.reference_density >= 0
        internal = self.internal(pairs) & held[:, None]
        if self.apart is not None:
            internal = internal | self.detached(pairs)
        seen = eqx.tree_at(
            lambda p: (p.valid, p.weight, p.offset),
            pairs,
            (
                pairs.valid & ~internal,
                jnp.where(internal, 0.0, pairs.weight),
                tuple(jnp.where(internal, 0.0, o) for o in pairs.offset),
            ),
        )
        own = jnp.where(held, self.reference_density, 0.0)
        return seen, number_density(seen) + own


def visible(coupling: Coupling | None, pairs: Pairs, r_e: float) -> Pairs:
    """`pairs` as the fluid stages see them: a pair with a hidden particle
    (`Coupling.hidden`) is no pair (not valid, no weight, no offset, distance
    r_e); the lists keep its index (a body model may read its own particles'
    rows). A pair's weight is times its partner's `Coupling.packing` and the
    geometric mean of its particles' `Coupling.pores`."""
    if coupling is None:
        return pairs
    if coupling.hidden is not None:
        hidden = coupling.hidden
        seen = ~(hidden[:, None] | take_rows(hidden, pairs.index))
        pairs = eqx.tree_at(
            lambda p: (p.valid, p.weight, p.offset, p.distance),
            pairs,
            (
                pairs.valid & seen,
                jnp.where(seen, pairs.weight, 0.0),
                tuple(jnp.where(seen, o, 0.0) for o in pairs.offset),
                jnp.where(seen, pairs.distance, r_e),
            ),
        )
    if coupling.packing is not None:
        weight = pairs.weight * take_rows(coupling.packing, pairs.index)
        pairs = eqx.tree_at(lambda p: p.weight, pairs, weight)
    if coupling.pores is not None:
        root = jnp.sqrt(coupling.pores)
        weight = pairs.weight * root[:, None] * take_rows(root, pairs.index)
        pairs = eqx.tree_at(lambda p: p.weight, pairs, weight)
    return pairs


def source_view(
    coupling: Coupling | None, pairs: Pairs
) -> tuple[Pairs, Float[Array, " n"]]:
    """`Coupling.source_view` of `pairs`; the pairs as they are without bodies."""
    if coupling is None:
        return pairs, number_density(pairs)
    return coupling.source_view(pairs)


class FluidLoad(eqx.Module):
    """What the fluid exerted on the particles in one step.

    The pressure force on a particle of volume l0^d is -l0^d `gradient`; for body
    particles `gradient` is the symmetric pair form over particles outside the body
    (`operators.SymmetricGradient`), so summed over a body it is exactly the force of
    the pairs across its surface.

    Attributes:
        pairs: the pair geometry at the predicted positions r* the pressure acted on.
        gradient: the pressure gradient each particle was corrected with [Pa/m],
            shape (n, d).
        wall_gradient: the part of `gradient` that wall particles contributed to
            body particles (zero for other particles) [Pa/m], shape (n, d).
        body_gradient: the part of the pair form that other bodies' particles
            contributed to body particles (zero for other particles) [Pa/m],
            shape (n, d), or None for none.
    """

    pairs: Pairs
    gradient: Float[Array, "n d"]
    wall_gradient: Float[Array, "n d"]
    body_gradient: Float[Array, "n d"] | None = None
