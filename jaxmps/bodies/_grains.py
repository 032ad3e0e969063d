"""DEM grains (seed 002 §5): spheres of one particle each, in contact with one
another and with the walls by Voigt springs and dashpots with a Coulomb slider,
and carried by the fluid through drag and lift.

The grains are hidden from the fluid (`Coupling.hidden`): the fluid flows through
them as if they were not there, and they feel it through the drag and lift of the
fluid velocity around them, with buoyancy as their submerged weight. They push
back on the particles of rigid and elastic bodies they touch, and, where asked
(`Grains.on_fluid`; seed 002 has "no reaction on the fluid"), on the fluid that
drags them. Each step, after the fluid stages, `Grains.advance` finds each
grain's contact candidates, carries the tangential springs of the contacts that
persist, and integrates the grains in sub-steps by symplectic Euler.
"""

import dataclasses
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .. import neighbours
from .._coupling import Coupling, FluidLoad
from .._numerics import is_concrete, safe_norm, take_rows
from .._params import Params
from .._result import Result, update_result
from .._state import State
from .._types import Kind, Scalar, is_kind
from ..neighbours import Grid
from ..operators import Discretisation
from ._base import AbstractBodyModel
from ._grain_laws import (
    _Material,
    _Walls,
    contact_forces,
    fluid_force,
    rule_step,
    sphere_volume,
    wendland_like,
)


def _up(gravity: Float[Array, " d"]) -> Float[Array, " d"]:
    """The unit vector against gravity (the last axis without gravity)."""
    norm = jnp.sqrt(jnp.sum(gravity**2))
    last = jnp.zeros_like(gravity).at[-1].set(1.0)
    return jnp.where(norm > 0, -gravity / jnp.where(norm > 0, norm, 1.0), last)


class Grains(AbstractBodyModel):
    """The DEM component of a Scene (seed 002 §5): m spherical grains of one
    particle each (`Kind.SEDIMENT`), touching one another and the wall particles
    (spheres of diameter l0, fixed or moved by the walls' motion).

    A contact of overlap delta > 0 and normal n (from the grain to its partner)
    pushes with F_n = max(k_n delta + eta_n delta_dot, 0) along -n and holds with
    the tangential spring and dashpot F_t = k_s s + eta_s v_t, |F_t| <= mu F_n
    (the Coulomb slider: on slip the spring s is capped at mu F_n / k_s), where s
    is the tangential displacement since the contact began (carried from step to
    step, turned into the contact's tangent plane, zeroed when it ends) and v_t
    the tangential velocity of the contact points, spins included. k_s = k_n /
    (2 (1 + nu_p)), eta_s = eta_n / sqrt(2 (1 + nu_p)) (seed 002 eq. 3.69-3.72);
    eta_n = 2 zeta sqrt(m* k_n) with m* the pair's reduced mass (the grain's own
    against a wall) and zeta the damping ratio of the restitution. The spin is
    driven by the torques (d/2 - delta/2) n x F_t, with I = m d^2 / 10 (a sphere;
    seed 002 leaves it open), and resisted by a rolling couple of at most mu_r
    R* F_n (`Params.grains.rolling`; 0, the seed's free rolling, by default).

    In water (`submerged`), a grain's mass and weight are those of its submerged
    density rho_s - rho_w (seed 002 §5.1: buoyancy as submerged weight, no added
    mass), and the fluid's drag and lift act on it (`fluid_force`) from the
    velocity u_f of the fluid around it, a w_s-weighted mean over its fluid
    neighbours after the fluid stages of the step, whose horizontal part is
    reduced by (1 - n_s / n_s0) where solid neighbours (grains, walls) crowd it
    (seed 002 eq. 3.80).

    The grains act back (`reacts`) through `Coupling.force`, one step later: the
    mean over the step's sub-steps of their contact forces on body particles
    (`on_bodies`: Newton's third law slot by slot, so blocks rest on grains and
    are rubbed by them; but a grain still attached to the bed is a wall to the
    bodies, which their own wall contact keeps off it, and feels them without
    pushing back), and, with `on_fluid`, minus their drag and lift, shared
    among the fluid neighbours of each grain by the w_s weights of its u_f. A
    grain stands for a sphere in 3-D; in 2-D (a sheet of unit depth) for a row of
    spheres of its diameter d along the third axis, so that its force per unit
    depth is F / d. # Choice: the seed's 2-D grains are spheres whose fluid and
    contact forces are a sphere's; their row at d apart fills the plane's packed
    bed as the seed's figures show. The lag of one step keeps the fluid and body
    stages as they are (the grains advance last); the impulse of a step reaches
    its partner whole, so momentum is kept over an exchange that ends.

    Attributes:
        count: number of grains m.
        spacing: the scene's particle spacing l0 [m] (the wall particles'
            diameter).
        grid: the cell grid of the grains' contact search (cells of the search
            radius).
        contact_capacity: contact slots per grain (static); more candidates end
            the run with `Result.contact_overflow`.
        substeps: DEM sub-steps per step (static).
        submerged: whether the grains lie in water (submerged density, fluid
            forces).
        on_bodies: whether the grains can touch body particles (rigid, elastic),
            which then feel their contacts.
        on_fluid: whether the fluid feels the grains' drag and lift back.
        bed: whether some grains start attached to the bed (`GrainState.attached`).
        detach_distance: an attached grain detaches for good once its centre
            is this many diameters from where it started.
        packing: n0 / n_s0, the weight of an attached grain's pairs in the
            fluid's sums (seed 002 eq. 3.73).
        search_radius: the contact search radius [m]: the largest contact
            distance and a skin that covers a step's motion of both partners.
        packed_density: n_s0, the solid number density of a packed bed, for the
            velocity correction (seed 002 eq. 3.80).
        poisson_ratio: nu_p of the tangential stiffness and damping (0.3 in the
            seed).
        courant: the largest step moves a grain at most courant l0.
    """

    name: ClassVar[str] = "grains"
    frame_fields: ClassVar[tuple[str, ...]] = (
        "spin",
        "contact_count",
        "fluid_force",
        "attached",
    )
    count: int
    spacing: float
    grid: Grid
    search_radius: float
    contact_capacity: int = 16
    substeps: int = 1
    submerged: bool = False
    on_bodies: bool = False
    on_fluid: bool = False
    bed: bool = False
    detach_distance: float = 0.5
    packing: float = 1.0
    packed_density: float = 1.0
    poisson_ratio: float = 0.3
    courant: float = 0.2
    # Choice: 0, seed 002's dashpots, which act in full from a contact's first
    # instant: the force jumps by eta delta_dot when a contact begins, in
    # whichever sub-step that falls, so a rollout is a piecewise function of the
    # parameters (measured: a bouncing grain's loss jumps by 1-2 % of its own
    # slope's scale between restitutions 2e-5 apart, and exact gradients over
    # three bounces were 30-600 times the secant). A positive ramp engages them
    # linearly over that share of the contact distance (`add_grains`).
    dashpot_ramp: float = 0.0

    def __check_init__(self):
        if self.count < 1:
            raise ValueError("Grains.count must be at least 1.")
        if self.substeps < 1:
            raise ValueError("Grains.substeps must be at least 1.")
        if self.contact_capacity < 1:
            raise ValueError("Grains.contact_capacity must be at least 1.")
        if not self.courant > 0:
            raise ValueError("Grains.courant must be positive.")
        if not -1.0 < self.poisson_ratio < 0.5:
            raise ValueError("Grains.poisson_ratio must lie in (-1, 0.5).")
        if not 0.0 <= self.dashpot_ramp < 1.0:
            raise ValueError("Grains.dashpot_ramp must lie in [0, 1).")
        if self.on_fluid and not self.submerged:
            raise ValueError("Grains.on_fluid needs grains in water (submerged).")
        if not self.detach_distance > 0:
            raise ValueError("Grains.detach_distance must be positive.")
        if not self.packing > 0:
            raise ValueError("Grains.packing must be positive.")

    @property
    def reacts(self) -> bool:
        """Whether the grains act on other particles (`GrainState.reaction`)."""
        return self.on_bodies or self.on_fluid

    def owner(self, state: State) -> Int[Array, " n"]:
        """Grains belong to no body (-1 everywhere)."""
        return jnp.full(state.position.shape[:1], -1, jnp.int32)

    def coupling(self, disc: Discretisation, params: Params, state: State) -> Coupling:
        """The grains are hidden from the fluid, but for those attached to the
        bed (`bed`), which are walls to it whose pairs weigh `packing`; what
        the grains pushed in the last step pushes back (`reacts`)."""
        del disc
        gs = state.grains
        n = state.position.shape[0]
        free = ~gs.attached if self.bed else True
        hidden = jnp.zeros((n,), bool).at[gs.index].set(free)
        packing = None
        if self.bed:
            share = jnp.where(gs.attached, self.packing, 1.0)
            packing = jnp.ones((n,), params.density.dtype).at[gs.index].set(share)
        return Coupling(
            density=jnp.full((n,), params.density, params.density.dtype),
            owner=self.owner(state),
            as_fluid=jnp.zeros((n,), bool),
            hidden=hidden,
            packing=packing,
            force=gs.reaction if self.reacts else None,
        )

    def effective_density(self, params: Params):
        """The density a grain is advanced with: rho_s - rho_w in water, else
        rho_s [kg/m^3]."""
        rho = params.grains.density
        return rho - params.density if self.submerged else rho

    def mass(self, params: Params, diameter):
        """Each grain's (effective) mass [kg]."""
        return self.effective_density(params) * sphere_volume(diameter)

    def substep_limit(self, params: Params, diameter) -> Scalar:
        """The largest DEM sub-step [s]: twice seed 002's rule step
        (`rule_step`) of the lightest grain, so that `jaxmps.Adaptive`'s default
        half of it takes the seed's step."""
        lightest = jnp.min(self.mass(params, diameter))
        return 2.0 * rule_step(lightest, params.grains.stiffness)

    def body_limit(self, params: Params, diameter, dim: int, xp=jnp):
        """The largest dt [s] at which a body particle feels the grains' contacts
        stably one step late (`on_bodies`; inf without): omega dt <= 1 for the
        lightest body particle (rho_b l0^d, per unit depth in 2-D) on one contact
        of stiffness k_n (k_n / d per unit depth in 2-D), omega^2 = k / m.
        # Choice: one particle's mass bounds the body's share per contact from
        # below (a rigid body spreads a contact over all its particles), so the
        # limit is safe for elastic particles and conservative for blocks: a
        # 2 x 4-particle block on grains measured stable up to omega dt = 2.6 and
        # unstable (a Courant failure) from 5.2.
        `xp` is jnp under a trace, numpy for the check before a run."""
        if not self.on_bodies:
            return xp.inf
        densities = [
            xp.min(xp.asarray(getattr(params, name).density))
            for name in ("rigid", "elastic")
            if getattr(params, name) is not None
        ]
        lightest = densities[0] if len(densities) == 1 else xp.minimum(*densities)
        mass = lightest * self.spacing**dim
        stiffness = xp.asarray(params.grains.stiffness)
        if dim == 2:
            stiffness = stiffness / xp.min(xp.asarray(diameter))
        return xp.sqrt(mass / stiffness)

    def time_step_limit(
        self, disc: Discretisation, params: Params, state: State
    ) -> Scalar:
        """The largest dt [s]: `substeps` sub-steps within `substep_limit`, a
        step that moves the fastest grain by at most `courant` l0, and the
        bodies' `body_limit`."""
        gs = state.grains
        steps = self.substeps * self.substep_limit(params, gs.diameter)
        steps = jnp.minimum(steps, self.body_limit(params, gs.diameter, disc.dim))
        velocity = state.velocity[gs.index]
        speed = jnp.max(jnp.sqrt(jnp.sum(velocity**2, axis=-1)))
        courant = jnp.where(
            speed > 0,
            self.courant * disc.spacing / jnp.where(speed > 0, speed, 1.0),
            jnp.inf,
        )
        return jax.lax.stop_gradient(jnp.minimum(steps, courant))

    def check(self, params: Params, state: State) -> None:
        g = params.grains
        for name in (
            "friction",
            "restitution",
            "density",
            "stiffness",
            "lift",
            "rolling",
            "release_time",
        ):
            if getattr(g, name) is None:
                continue
            shape = getattr(g, name).shape
            if shape != ():
                raise ValueError(
                    f"Params.grains.{name} has shape {shape}; the grains of a Scene "
                    "share one value (shape ()). For a batch of values use "
                    "`jaxmps.sweep` or `jax.vmap` over Params."
                )
        if is_concrete(g.density, params.density) and self.submerged:
            if not float(g.density) > float(params.density):
                raise ValueError(
                    f"Params.grains.density = {float(g.density):g} kg/m^3 is not "
                    f"above the fluid's {float(params.density):g}: grains in water "
                    "are advanced with their submerged weight, and a grain that "
                    "floats is not modelled. Give a denser grain_density."
                )
        self.check_time_step(params, state)

    def check_time_step(self, params: Params, state: State) -> None:
        """Refuse a concrete dt beyond `substeps` sub-steps of the DEM limit
        (computed in NumPy: under a trace, even concrete values are staged)."""
        g = params.grains
        values = (params.dt, g.density, g.stiffness, params.density)
        if not is_concrete(*values, state.grains.diameter):
            return
        dt, density, stiffness, water = (float(v) for v in values)
        rho = density - water if self.submerged else density
        lightest = rho * sphere_volume(float(np.asarray(state.grains.diameter).min()))
        limit = self.substeps * 2.0 * rule_step(lightest, stiffness)
        if dt > limit * (1 + 1e-9):
            raise ValueError(
                f"Params.dt = {dt:.3g} s is beyond the grains' contact limit "
                f"{limit:.3g} s (substeps={self.substeps} x 2 x (pi/10) sqrt(m / "
                f"(2 k_n)), stiffness={stiffness:.4g} N/m): lower dt, lower "
                "Params.grains.stiffness, or take more DEM sub-steps per step "
                "(`add_grains(..., substeps=...)`, scene setting `substeps`)."
            )

    def check_body_step(self, params: Params, state: State) -> None:
        """Refuse a concrete dt beyond `body_limit` (a run of fixed steps; under
        `jaxmps.Adaptive` the limit bounds every step instead)."""
        bodies = [getattr(params, name) for name in ("rigid", "elastic")]
        densities = [b.density for b in bodies if b is not None]
        values = (params.dt, params.grains.stiffness, state.grains.diameter)
        if not self.on_bodies or not is_concrete(*values, *densities):
            return
        dt, stiffness = float(params.dt), float(params.grains.stiffness)
        dim = state.position.shape[1]
        limit = float(self.body_limit(params, state.grains.diameter, dim, np))
        if dt > limit * (1 + 1e-9):
            raise ValueError(
                f"Params.dt = {dt:.3g} s is beyond the limit {limit:.3g} s at which "
                "the bodies feel the grains' contacts stably (one body particle of "
                f"the lightest body on one contact of stiffness={stiffness:.4g} N/m, "
                "omega dt <= 1): lower dt (or let the run choose it, scene "
                "setting dt='adaptive'), lower Params.grains.stiffness, make the "
                "bodies denser, or let the bodies not feel the grains "
                "(`add_grains(..., on_bodies=False)`)."
            )

    def advance(
        self, disc: Discretisation, params: Params, state: State, load: FluidLoad
    ) -> State:
        """One step of the grains, after the fluid stages (seed 002 §5.7): the
        fluid velocity around each grain, the contact candidates and their
        carried springs, then `substeps` symplectic-Euler sub-steps of the
        contact, fluid and gravity forces (`_integrate`); what they pushed
        (`_reaction`), the bed's detachments (`_detach`); flags contact overflow
        and a step beyond the grains' limits."""
        gs = state.grains
        x = state.position[gs.index]
        walls = _Walls(
            position=state.position[gs.walls],
            velocity=state.velocity[gs.walls],
            active=state.active[gs.walls],
            diameter=self.spacing,
        )
        partner, shear, overflow = self._candidates(state, x, walls)
        # In 2-D a grain is a row of spheres d apart: per unit depth, F / d.
        reach = 1.0 / gs.diameter if disc.dim == 2 else jnp.ones_like(gs.diameter)
        (x, v, spin, shear), (fluid, count, on_walls) = self._integrate(
            disc, params, state, load, walls, partner, shear, reach
        )
        active = state.active[gs.index]
        x = jnp.where(active[:, None], x, state.position[gs.index])
        v = jnp.where(active[:, None], v, 0.0)
        reaction = gs.reaction
        if self.reacts:
            reaction = self._reaction(disc, state, load, on_walls, fluid, reach)
        attached, kind, origin = self._detach(params, state, x)
        grains = dataclasses.replace(
            gs,
            partner=partner,
            shear=shear,
            spin=spin,
            fluid_force=fluid[-1],
            contact_count=count[-1],
            reaction=reaction,
            attached=attached,
            origin=origin,
        )
        result = update_result(state.result, overflow, Result.contact_overflow)
        result = update_result(
            result, self._beyond(disc, params, gs, v), Result.step_too_large
        )
        return dataclasses.replace(
            state,
            position=state.position.at[gs.index].set(x),
            velocity=state.velocity.at[gs.index].set(v),
            kind=kind,
            grains=grains,
            result=result,
        )

    def _integrate(self, disc, params, state, load, walls, partner, shear, reach):
        """The `substeps` symplectic-Euler sub-steps of the step: the final
        (positions, velocities, spins, springs) and, per sub-step, the fluid
        force on each grain, its contact count and (`reacts`) the force on each
        wall particle."""
        gs, g = state.grains, params.grains
        up = _up(params.gravity)
        x, v = state.position[gs.index], state.velocity[gs.index]
        flow = (
            self._fluid_velocity(disc, state, load, up)
            if self.submerged
            else jnp.zeros_like(x)
        )
        mass = self.mass(params, gs.diameter)
        inertia = 0.1 * mass * gs.diameter**2
        material = _Material.of(self, params, mass)
        h = params.dt / self.substeps
        weight = None
        if self.reacts:
            # A grain in the bed is a wall to the bodies (their own wall contact
            # pushes them off it), so it pushes them no further; it meets them
            # as DEM partners all the same, so that settling under its weight
            # it does not sink into a block resting beside it.
            weight = jnp.where(gs.attached, 0.0, reach) if self.bed else reach
        free = self.released(params, state)

        def substep(carry, _):
            x, v, spin, shear = carry
            contact = contact_forces(
                x, v, spin, gs.diameter, partner, shear, walls, material, h, weight
            )
            fluid = (
                jnp.where(
                    free,
                    fluid_force(
                        flow - v,
                        gs.diameter,
                        params.density,
                        params.viscosity,
                        g.lift,
                        up,
                    ),
                    0.0,
                )
                if self.submerged
                else jnp.zeros_like(v)
            )
            force = contact.force + fluid + mass[:, None] * params.gravity[None, :]
            v = v + h * force / mass[:, None]
            x = x + h * v
            spin = spin + h * contact.torque / inertia[:, None]
            out = (fluid, contact.count, contact.wall_force)
            return (x, v, spin, contact.shear), out

        carry = (x, v, gs.spin, shear)
        return jax.lax.scan(substep, carry, None, length=self.substeps)

    def released(self, params: Params, state: State):
        """Whether the grains are past `GrainParams.release_time` (always
        without one). Before it they feel no fluid force and settle under their
        own (submerged) weight while the flow spins up over them, and the bed's
        grains are placed where they lie (`_detach`): seed 002 spins its scour
        runs up with the grains fixed."""
        release = params.grains.release_time
        return True if release is None else state.time >= release

    def _detach(self, params: Params, state: State, x):
        """The grains still attached after the step, the kinds and the places
        the bed's grains are measured from: a grain of the bed (`bed`) that has
        left its place is free for good (seed 002 §5.5). # Choice: "left" is
        moved `detach_distance` diameters from its place (the seed gives no
        criterion), the place where it lay at `GrainParams.release_time` (its
        start without one), so that a packed bed's settling under its own
        weight (measured: a hexagonal packing's grains beside a pit's walls
        sink by half a diameter, having no support on every other row) is not
        read as erosion."""
        gs, kind = state.grains, state.kind
        if not self.bed:
            return gs.attached, kind, gs.origin
        free = self.released(params, state)
        origin = jnp.where(free, gs.origin, x)
        moved = (
            jnp.sum((x - origin) ** 2, axis=-1)
            > (self.detach_distance * gs.diameter) ** 2
        )
        attached = gs.attached & ~moved
        now = jnp.where(attached, int(Kind.WALL), int(Kind.SEDIMENT))
        return attached, kind.at[gs.index].set(now.astype(kind.dtype)), origin

    def _beyond(self, disc, params, gs, v):
        """Whether the step was beyond the grains' limits: the sub-steps', the
        bodies' (`body_limit`), or moving a grain more than `courant` l0."""
        speed = jnp.sqrt(jnp.max(jnp.sum(v**2, axis=-1)))
        limit = self.substeps * self.substep_limit(params, gs.diameter)
        limit = jnp.minimum(limit, self.body_limit(params, gs.diameter, disc.dim))
        dt = params.dt
        return (dt > limit * (1 + 1e-9)) | (speed * dt > self.courant * self.spacing)

    def _reaction(self, disc, state, load, on_walls, fluid, reach):
        """What the grains exerted over the step, per unit volume of each
        particle [N/m^3]: the sub-steps' mean contact force on each wall
        particle, and minus the mean drag and lift on each grain shared among
        its fluid neighbours by their w_s weights (`on_fluid`)."""
        gs = state.grains
        volume = disc.spacing**disc.dim
        n, dim = state.position.shape
        reaction = jnp.zeros((n, dim), state.position.dtype)
        reaction = reaction.at[gs.walls].add(jnp.mean(on_walls, axis=0) / volume)
        if self.on_fluid:
            index, share, _ = self._fluid_shares(disc, state, load)
            push = -jnp.mean(fluid, axis=0) * reach[:, None] / volume
            target = jnp.where(share > 0, index, n)
            for a in range(dim):
                part = share * push[:, a, None]
                reaction = reaction.at[target, a].add(part, mode="drop")
        return reaction

    def _candidates(self, state: State, x, walls: "_Walls"):
        """Each grain's contact candidates at the step's start (grains and walls
        within `search_radius`), its carried tangential springs (those of
        partners it had before, zero for new ones) and whether a grain had more
        candidates than slots."""
        gs = state.grains
        m, k = self.count, self.contact_capacity
        x_dem = jnp.concatenate([x, walls.position])
        active = jnp.concatenate([state.active[gs.index], walls.active])
        found = neighbours.build(self.grid, x_dem, active, k, self.search_radius)
        partner = found.index[:m]
        overflow = (jnp.max(found.count[:m]) > k) | found.cell_overflow
        total = x_dem.shape[0]
        # The carried spring of each new slot: the old slot with the same partner.
        same = (partner[:, :, None] == gs.partner[:, None, :]) & (
            partner[:, :, None] < total
        )
        shear = jnp.stack(
            [jnp.sum(jnp.where(same, s[:, None, :], 0.0), axis=-1) for s in gs.shear]
        )
        return partner, shear, overflow

    def _fluid_shares(self, disc: Discretisation, state: State, load: FluidLoad):
        """Each grain's neighbour slots and their shares w_s / sum w_s over its
        fluid neighbours (0 elsewhere, all 0 with none), and the number density
        n_s of its solid neighbours (grains, walls and dummies)."""
        gs = state.grains
        index = load.pairs.index[gs.index]
        n = state.position.shape[0]
        listed = index < n
        x = state.position
        offset = tuple(
            jnp.where(listed, take_rows(x[:, a], index) - x[gs.index, a, None], 0.0)
            for a in range(disc.dim)
        )
        distance = safe_norm(offset, listed, placeholder=disc.r_e)
        near = listed & (distance < disc.r_e)
        kind, active = state.kind, state.active
        fluid = take_rows(active & (kind == int(Kind.FLUID)), index) & near
        solid_kinds = (Kind.SEDIMENT, Kind.WALL, Kind.DUMMY)
        solid = take_rows(active & is_kind(kind, solid_kinds), index) & near
        w_s = jnp.where(fluid, wendland_like(distance, disc.r_e), 0.0)
        total = jnp.sum(w_s, axis=1, keepdims=True)
        share = w_s / jnp.where(total > 0, total, 1.0)
        n_s = jnp.sum(disc.weight(distance, solid, disc.r_e), axis=1)
        return index, share, n_s

    def _fluid_velocity(
        self, disc: Discretisation, state: State, load: FluidLoad, up
    ) -> Float[Array, "m d"]:
        """u_f of each grain (seed 002 eq. 3.78-3.80): the w_s-weighted mean
        velocity of its fluid neighbours (0 with none), its horizontal part
        times 1 - min(n_s / n_s0, 1), n_s the number density of its solid
        neighbours (grains, walls and dummies)."""
        index, share, n_s = self._fluid_shares(disc, state, load)
        u = jnp.stack(
            [
                jnp.sum(share * take_rows(state.velocity[:, a], index), axis=1)
                for a in range(disc.dim)
            ],
            axis=-1,
        )
        open_share = 1.0 - jnp.clip(n_s / self.packed_density, 0.0, 1.0)
        vertical = jnp.sum(u * up[None, :], axis=-1)[:, None] * up[None, :]
        return vertical + open_share[:, None] * (u - vertical)
