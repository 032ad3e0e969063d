"""Rigid bodies moved as fluid, then projected onto a rigid motion (seed 000 §4,
seed 002 §4): the passively moving solid of Koshizuka et al."""

import dataclasses
import functools
import itertools
import math
from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int, Shaped

from .._coupling import Coupling, FluidLoad
from .._numerics import (
    einsum,
    materialised,
    matmul,
    pair_sum,
    safe_norm,
    take_rows,
)
from .._params import Params
from .._state import State
from .._types import Kind
from ..operators import Discretisation
from . import rotation as rot
from ._base import AbstractBodyModel
from ._friction import Contact, ContactReaction, Coulomb


class RigidBodies(AbstractBodyModel):
    """The rigid-body component of a Scene (present only in scenes with bodies).

    Each step the body particles are advanced by the fluid stages exactly like fluid
    of the body's density (gravity, viscosity, pressure gradient / rho_body); the
    tentative velocities are then projected onto one rigid motion per body that keeps
    the body's linear momentum and its angular momentum about the centre (seed 000
    eq. 2.5-1...2.5-10, with the digest's corrected signs). Positions are rebuilt from
    each body's centre, orientation and fixed body-frame offsets, so shapes never
    drift. Contact with walls and other bodies acts through the pressure (and the
    collision guard), as in both seeds; `friction` adds Coulomb friction against walls.

    Attributes:
        count: number of bodies b.
        friction: the friction law against walls, or None for frictionless contact.
        contact_distance: a wall particle closer than this (in units of l0) to a body
            particle puts the body in contact.
        pressure: how the pressure acts on the body particles (`fluid.pressure_force`):
            "pairs", the momentum-conserving pair form across the body's surface
            (forces between bodies and against walls equal and opposite pair by
            pair; what the `ContactReaction` friction normal needs), or "fluid", the
            fluid's own gradient, as on the fluid the body replaces (seed 000 §4:
            buoyancy consistent to first order, floating bodies at Archimedes'
            draft; the pair form floats them 0.3-0.8 l0 too deep).
        contact_stiffness, contact_damping: the contact force (`_push`).
        friction_sweeps: sweeps of the friction between bodies (`_rub_bodies`).
        particles: how many particle slots hold body particles (the friction
            between bodies runs over these alone); None: all slots.
    """

    name: ClassVar[str] = "rigid"
    frame_fields: ClassVar[tuple[str, ...]] = (
        "centre",
        "orientation",
        "velocity",
        "angular_velocity",
        "force",
        "torque",
        "contact_force",
        "friction",
        "impulse",
    )
    count: int
    friction: Coulomb | None = Coulomb()
    # Choice: seed 000's contact indicator is r < l0, but a body resting on a wall sits
    # at exactly r = l0 on the lattice, so the strict test flickers; 1.5 l0 catches
    # the first wall layer and not the second.
    contact_distance: float = 1.5
    # Choice: "pairs" by default, so that contact and friction keep the reaction
    # they are built on; floating scenes without friction choose "fluid".
    pressure: str = "pairs"
    # Choice: a stiff, damped contact force (see `_push`); 0 leaves contact to the
    # pressure alone, as both seeds do.
    contact_stiffness: float = 0.2
    contact_damping: float = 0.7
    # Choice: 64 Jacobi sweeps of the friction between bodies (see `_rub_bodies`)
    # hold a stack of three blocks within 0.005 mm over 1 s (32: 0.2 mm); they
    # run over the body particles alone (`particles`, set by `add_rigid_bodies`).
    friction_sweeps: int = 64
    particles: int | None = None

    def __check_init__(self):
        if self.count < 1:
            raise ValueError("RigidBodies.count must be at least 1.")
        if not self.contact_distance > 0:
            raise ValueError("RigidBodies.contact_distance must be positive.")
        if not 0 <= self.contact_stiffness <= 0.5:
            raise ValueError(
                "RigidBodies.contact_stiffness must be in [0, 0.5] (a fraction of "
                f"the explicit limit), got {self.contact_stiffness}."
            )
        if not 0 <= self.contact_damping <= 1:
            raise ValueError(
                "RigidBodies.contact_damping must be in [0, 1] (a damping ratio), "
                f"got {self.contact_damping}."
            )
        if not (isinstance(self.friction_sweeps, int) and self.friction_sweeps >= 1):
            raise ValueError(
                "RigidBodies.friction_sweeps (friction between bodies) must be a "
                f"whole number >= 1, got {self.friction_sweeps!r}."
            )
        if self.pressure not in ("pairs", "fluid"):
            raise ValueError(
                f"RigidBodies.pressure must be 'pairs' or 'fluid', got "
                f"{self.pressure!r}."
            )
        if (
            self.pressure == "fluid"
            and self.friction is not None
            and isinstance(self.friction.normal, ContactReaction)
        ):
            raise ValueError(
                "pressure='fluid' with a friction law whose normal force is the "
                "ContactReaction: that reaction is the pair form's, which the bodies "
                "do not receive with pressure='fluid'. Use pressure='pairs', "
                "friction=None, or Coulomb(normal=ContactPressure()) or "
                "SubmergedWeight()."
            )

    def check(self, params: Params, state: State) -> None:
        """One value per body in the parameters and the sub-state (ValueError)."""
        b = self.count
        shapes = {
            "Params.rigid.density": params.rigid.density.shape,
            "Params.rigid.mu_static": params.rigid.mu_static.shape,
            "Params.rigid.mu_kinetic": params.rigid.mu_kinetic.shape,
            "State.rigid.centre": state.rigid.centre.shape[-2:-1],
        }
        for name, shape in shapes.items():
            if shape != (b,):
                raise ValueError(
                    f"{name} has shape {shape} but the Scene has {b} rigid bodies "
                    f"(expected ({b},)). For a batch of values use `jaxmps.sweep` "
                    "or `jax.vmap` over Params."
                )
        dim = state.position.shape[-1]
        expected = {
            "centre_of_mass": ((b, dim), "d components"),
            "gyration": (
                (b, rot.spin_size(dim)),
                "one radius per body-frame axis: 1 in 2-D, 3 in 3-D",
            ),
            "release_time": ((b,), "one time per body"),
        }
        for name, (shape, rows) in expected.items():
            value = getattr(params.rigid, name)
            if value is not None and value.shape != shape:
                raise ValueError(
                    f"Params.rigid.{name} has shape {value.shape}; expected {shape} "
                    f"(one row per body of the Scene's {b}, {rows})."
                )

    def owner(self, state: State) -> Int[Array, " n"]:
        """Each particle's body, -1 for none (rigid bodies are numbered first)."""
        return state.rigid.body

    def coupling(self, disc: Discretisation, params: Params, state: State) -> Coupling:
        """Body particles are advanced with their body's density (seed 000 §4.3: the
        pressure acceleration of a body particle is -grad P / rho_body), and the
        particles of one body exert no fluid force on each other."""
        del disc
        body = self.owner(state)
        rho = take_rows(params.rigid.density, jnp.where(body >= 0, body, body.shape[0]))
        return Coupling(
            density=jnp.where(body >= 0, rho, params.density),
            owner=body,
            as_fluid=(body >= 0) & (self.pressure == "fluid"),
            between_bodies=self.count > 1 and self.friction is not None,
            pressed=self.pressure == "fluid",
        )

    def advance(
        self, disc: Discretisation, params: Params, state: State, load: FluidLoad
    ) -> State:
        """Project the body particles (as advanced by the fluid stages, with
        tentative velocities u^) onto rigid motions, apply friction, and move them.

        The fluid stages change each body particle's velocity by dt (g + a_i), a_i
        the fluid's acceleration of a particle of mass m = rho_b l0^d. The body of
        mass M = N m, centre of mass G and inertia I_G takes their momentum and
        their angular momentum about G, gravity acting at G:
            M V_G' = M V_G + m sum (u^_i - u_i),
            L' = I_G omega + m sum (r_i - r_G) x (u^_i - u_i - dt g),
        u_i the particles' rigid velocities at step k. For a uniform body (G the
        particles' centroid, I_G theirs) this is seed 000's projection of the
        tentative displacements (eq. 2.5-4/5): V = (1/N) sum u^_i, L = m sum
        (r_i - r_g) x u^_i. Then r_G^{k+1} = r_G^k + dt V_G' and the orientation
        turns by dt I_k^-1 L' (I_k the inertia at step k, eq. 2.5-9/10); the
        particles get v_i = V_G' + omega x (r_i - r_G) with omega = I_{k+1}^-1 L',
        so a free body keeps L' exactly. The state holds the centroid's motion.
        """
        rs = state.rigid
        dim, count, dt = disc.dim, self.count, params.dt
        member = is_body(state)
        segment = jnp.where(member, rs.body, count)
        index = jnp.where(member, rs.body, 0)

        def body_sum(x):
            keep = member.reshape((-1,) + (1,) * (x.ndim - 1))
            return _segment_sum(jnp.where(keep, x, 0), segment, count)

        number = body_sum(jnp.ones_like(state.pressure))
        particle_mass = params.rigid.density * disc.volume
        mass = particle_mass * number
        rotation_k = rot.matrix(rs.orientation, dim)
        offset_body = self._offset(params, rs.centre)
        inertia_body = self._inertia(params, rs, particle_mass, mass, body_sum)
        inertia_k = _world(inertia_body, rotation_k, dim)

        arm_k = einsum("nij,nj->ni", rotation_k[index], rs.reference)
        offset_k = einsum("bij,bj->bi", rotation_k, offset_body)
        rigid_k = rs.velocity[index] + rot.spin_cross(rs.angular_velocity[index], arm_k)
        change = state.velocity - rigid_k
        velocity_k = rs.velocity + rot.spin_cross(rs.angular_velocity, offset_k)
        velocity = velocity_k + body_sum(change) / number[:, None]
        lever = arm_k - offset_k[index]
        momentum_k = einsum("bij,bj->bi", inertia_k, rs.angular_velocity)
        momentum_l = momentum_k + particle_mass[:, None] * body_sum(
            rot.cross(lever, change - dt * params.gravity[None, :])
        )

        velocity, momentum_l, contact, friction, sliding, reaction = self._touch(
            disc,
            params,
            state,
            load,
            body_sum,
            (arm_k, rigid_k, lever),
            (velocity, momentum_l),
            (mass, number, offset_k, inertia_k),
        )
        force = mass[:, None] * ((velocity - velocity_k) / dt - params.gravity[None, :])
        torque = (momentum_l - momentum_k) / dt
        velocity, momentum_l = _held(params, state.time, velocity, momentum_l)

        omega_k = jnp.linalg.solve(inertia_k, momentum_l[..., None])[..., 0]
        centre_of_mass = rs.centre + offset_k + dt * velocity
        orientation = rot.rotate(rs.orientation, dt * omega_k, dim)
        rotation = rot.matrix(orientation, dim)
        omega = jnp.linalg.solve(
            _world(inertia_body, rotation, dim), momentum_l[..., None]
        )[..., 0]
        offset = einsum("bij,bj->bi", rotation, offset_body)
        centre = centre_of_mass - offset
        centre_velocity = velocity - rot.spin_cross(omega, offset)

        arm = einsum("nij,nj->ni", rotation[index], rs.reference)
        position = centre[index] + arm
        particle_velocity = centre_velocity[index] + rot.spin_cross(omega[index], arm)
        rigid = dataclasses.replace(
            rs,
            centre=centre,
            orientation=orientation,
            velocity=centre_velocity,
            angular_velocity=omega,
            force=force,
            torque=torque,
            contact_force=contact.force,
            impulse=rs.impulse + dt * force,
            angular_impulse=rs.angular_impulse + dt * torque,
            friction=friction,
            sliding=sliding,
            wall_push=reaction,
        )
        return dataclasses.replace(
            state,
            position=jnp.where(member[:, None], position, state.position),
            velocity=jnp.where(member[:, None], particle_velocity, state.velocity),
            rigid=rigid,
        )

    def _touch(self, disc, params, state, load, body_sum, particles, motion, bodies):
        """Contact and friction: the contact force (walls, other bodies), then
        friction against walls, then between bodies. `particles` = (arm, rigid
        velocity at step k, lever about the centre of mass) per particle,
        `motion` = (centre-of-mass velocity, angular momentum) per body after the
        fluid, `bodies` = (mass, particle count, centre-of-mass offset, world
        inertia). Returns the motion after them, the wall contact, the wall
        friction force, whether each body slides and the push's reaction on the
        wall particles (`RigidState.wall_push`)."""
        arm_k, rigid_k, lever = particles
        velocity, momentum_l = motion
        mass, number, offset_k, inertia_k = bodies
        dt = params.dt
        outward = _outward(load.pairs, _solids(state))
        from_wall, from_bodies, exchange = self._push(
            disc, params, state, load, mass, rigid_k, body_sum, outward
        )
        push = from_wall + exchange.total
        velocity = velocity + dt * body_sum(push) / mass[:, None]
        momentum_l = momentum_l + dt * body_sum(
            rot.cross(lever, push) + exchange.moment
        )
        contact, touching = self._contact(
            disc, state, load, body_sum, arm_k, outward, from_wall
        )
        index = jnp.where(is_body(state), state.rigid.body, 0)
        reach = functools.partial(
            _reach, touching, index, arm_k - contact.arm[index], self.count
        )
        rub = functools.partial(
            self._rub,
            disc,
            params,
            contact,
            mass=mass,
            number=number,
            offset=offset_k,
            inertia=inertia_k,
            reach=reach,
        )
        walled = rub(velocity, momentum_l)
        reaction = _wall_reaction(
            state, load.pairs, from_wall, self.contact_distance * disc.spacing
        )
        if self.friction is None or self.count < 2:
            return *walled[:2], contact, *walled[2:], reaction
        spare = self.friction.spare(
            contact,
            velocity - contact.wall_velocity,
            mass,
            disc.volume * number,
            params.rigid.mu_static,
            params,
            disc.spacing,
            disc.dim,
        )
        change, turn, anchored = self._rub_bodies(
            disc,
            params,
            state,
            load,
            walled[0],
            walled[1],
            mass,
            lever,
            inertia_k,
            (from_bodies, exchange.total - from_bodies),
            outward,
            spare,
        )
        # an anchored body's walls take the other bodies' friction on it as well
        held = rub(velocity + change, momentum_l + turn)
        loose = (walled[0] + change, walled[1] + turn, *walled[2:])
        velocity, momentum_l, friction, sliding = (
            jnp.where(anchored.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)
            for a, b in zip(held, loose)
        )
        return velocity, momentum_l, contact, friction, sliding, reaction

    def _offset(self, params: Params, centre: Float[Array, "b d"]):
        """Each body's centre of mass from its particles' centroid, body frame."""
        offset = params.rigid.centre_of_mass
        return jnp.zeros_like(centre) if offset is None else offset.astype(centre.dtype)

    def _inertia(self, params: Params, rs, particle_mass, mass, body_sum):
        """Each body's inertia about its centre of mass in the body frame: from the
        radii of gyration, or that of its particles."""
        dim = rs.reference.shape[-1]
        gyration = params.rigid.gyration
        if gyration is None:
            offset = self._offset(params, rs.centre)
            index = jnp.where(rs.body >= 0, rs.body, 0)
            own = rot.inertia_of(rs.reference - offset[index])
            return particle_mass[:, None, None] * body_sum(own)
        moments = mass[:, None] * gyration.astype(mass.dtype) ** 2
        if dim == 2:
            return moments[:, :, None]
        return moments[:, :, None] * jnp.eye(3, dtype=mass.dtype)[None]

    def _rub(
        self,
        disc: Discretisation,
        params: Params,
        contact: Contact,
        velocity: Float[Array, "b d"],
        momentum_l: Float[Array, "b a"],
        mass: Float[Array, " b"],
        number: Float[Array, " b"],
        offset: Float[Array, "b d"],
        inertia: Float[Array, "b a a"],
        reach: Callable[[Float[Array, "b d"]], Float[Array, " b"]],
    ) -> tuple[
        Float[Array, "b d"], Float[Array, "b a"], Float[Array, "b d"], Bool[Array, " b"]
    ]:
        """Friction against walls: (velocity of the centre of mass, angular
        momentum about it) after the friction impulse, the friction force, and
        whether each body slides. The law sees the centre's velocity relative to
        the walls it touches (moving walls carry a body that sticks to them).
        With the friction torque the impulse acts at the contact's mean point and
        the contact face's normal forces add their couple (`_face`)."""
        count = self.count
        if self.friction is None:
            return (
                velocity,
                momentum_l,
                jnp.zeros_like(velocity),
                jnp.zeros(count, bool),
            )
        volume = disc.volume * number
        impulse, sliding = self.friction(
            contact,
            velocity - contact.wall_velocity,
            mass,
            volume,
            params.rigid.mu_static,
            params.rigid.mu_kinetic,
            params,
            disc.spacing,
            disc.dim,
        )
        if self.friction.torque:
            momentum_l = momentum_l + self._face(
                disc,
                params,
                contact,
                momentum_l,
                impulse,
                offset,
                inertia,
                reach,
                law_normal=self.friction.normal(
                    contact, mass, volume, params, disc.spacing, disc.dim
                ),
            )
        return (
            velocity + impulse / mass[:, None],
            momentum_l,
            impulse / params.dt,
            sliding,
        )

    def _face(
        self,
        disc: Discretisation,
        params: Params,
        contact: Contact,
        momentum_l: Float[Array, "b a"],
        impulse: Float[Array, "b d"],
        offset: Float[Array, "b d"],
        inertia: Float[Array, "b a a"],
        reach: Callable[[Float[Array, "b d"]], Float[Array, " b"]],
        law_normal: Float[Array, " b"],
    ) -> Float[Array, "b a"]:
        """The change of angular momentum that the friction impulse J (acting at
        the contact's mean point r_C) and the contact face's normal forces make.

        The face's normal forces stop the body tipping (every component of
        omega but the spin about the normal n) while their resultant stays on
        the face. The walls' forces of this step already gave a moment M_C about
        r_C; the face adds the couple K that makes their total
            K + dt M_C = I omega_n - L - r_C x J + dt M_C
        (its part normal to n), at most N dt e in size: N the friction law's
        normal force, e the farthest touching particle from r_C along n x K / |K|
        (the lever that total needs). Beyond that the face gives N dt e and the
        body turns with the rest (it tips).

        # Choice: with the law at the contact point alone (a point contact, the
        # effective mass 1/(1/M + (r x t).I^-1 (r x t))) a block on its face turned
        # a share 1 - m_eff / M of its load into rotation each step, which the
        # contact push damped away: a block below its coefficient crept (0.3 mm
        # in 0.5 s, dry, tan = 0.9 mu), one above it slid 13 % too far (tan = 1.1
        # mu), two touching blocks in water crept 13-15 mm in 0.5 s at tan = 0.91
        # mu, and a block twice as tall as wide tipped at 0.95 of its static
        # limit. Stopping the centre without the face's couple pushed the bottom
        # of a tipping block uphill and drove the tipping on (a cube toppled at
        # tan = 0.97). The limit on the total (not on K alone) counts the moment
        # the walls' pressure and push already carry: a suddenly tilted cube then
        # stands to 0.98 of its static limit (the push's unloading dips N by 5 %
        # for a step) and tips beyond it.
        """
        dim = disc.dim
        n = contact.normal
        arm = contact.arm - offset
        if dim == 2:
            spin = jnp.zeros_like(momentum_l)
        else:
            omega = jnp.linalg.solve(inertia, momentum_l[..., None])[..., 0]
            about_n = jnp.sum(omega * n, -1, keepdims=True) * n
            spin = einsum("bij,bj->bi", inertia, about_n)
        walls = params.dt * contact.moment
        total = spin - momentum_l - rot.cross(arm, impulse) + walls
        if dim == 3:  # normal forces give no moment about the normal
            total = total - jnp.sum(total * n, -1, keepdims=True) * n
            walls = walls - jnp.sum(walls * n, -1, keepdims=True) * n
        size = safe_norm(total, contact.touching, placeholder=0.0)
        unit = total / jnp.where(size > 0, size, 1.0)[:, None]
        if dim == 2:
            lever = unit * jnp.stack([n[:, 1], -n[:, 0]], axis=-1)
        else:
            lever = jnp.cross(n, unit)
        most = law_normal * params.dt * reach(lever)
        scale = jnp.minimum(1.0, most / jnp.where(size > 0, size, 1.0))
        couple = jnp.where(contact.touching[:, None], scale[:, None] * total - walls, 0)
        return rot.cross(arm, impulse) + couple

    def _push(
        self,
        disc: Discretisation,
        params: Params,
        state: State,
        load: FluidLoad,
        mass: Float[Array, " b"],
        rigid_k: Float[Array, "n d"],
        body_sum: Callable[[Shaped[Array, "n ..."]], Shaped[Array, "b ..."]],
        outward: Float[Array, "n d"],
    ) -> tuple[Float[Array, "n d"], Float[Array, "n d"], "Exchange"]:
        """The contact force on each body particle [N] from the walls; that from
        the other bodies on the particles of the lower-index body of each
        contact; and that exchange with its reactions (at the predicted positions
        of the step).

        A body particle i with wall particles within the contact distance gets a
        surface normal n_i and a gap h_i from the partners that face it (the mean
        of their normals, the least distance from their planes; see
        `_wall_surface`), and the force
            F_i = max(k (l0 - h_i) - c v_n, 0) n_i   where h_i < l0,
        v_n the normal velocity of i's rigid motion at step k relative to the
        partners' mean. Between two bodies the same force acts on each particle
        i of the body of lower index, the other body's particles its surface
        (their faces and i's own, in the bodies' frames: `_pair_gaps`), and
        back on the partners closer than l0 at the pairs' middles: contact
        between bodies keeps momentum and angular momentum.

        # Choice: the pressure carries a resting body (its particles sit l0 from the
        # wall), but a body's edge particles are free-surface particles with P = 0,
        # so the pressure's centre never reaches the edge a tipping body turns on:
        # a cube on a slope toppled at tan(theta) = 0.76 (friction torque on). This
        # force acts at the edge. It acts along the surface normal, not along
        # each pair: pair forces against a wall's particles make a lattice of
        # bumps that slowed a sliding block by 12-40 %, and between bodies
        # 12-22 % in 0.5 s (see `_push_between_bodies`). A gap along the mean
        # normal of a small body's particles, whose corners point diagonally,
        # pushed resting blocks apart: hence the faces. The stiffness is
        # tied to the step, not to a material: k = kappa m_c / dt^2 with m_c = M /
        # (the body's particles in contact), so a body pressed along its whole
        # face oscillates at omega dt = sqrt(kappa),
        # one on a corner at most sqrt(3 kappa) (kappa = `contact_stiffness` <=
        # 0.5, the explicit limit being 4); c = 2 zeta sqrt(k m_c) (zeta =
        # `contact_damping`); between bodies m_c is the pair's reduced value. Under
        # its weight a body sinks about g dt^2 / kappa into the wall: thousandths of
        # l0 at the fluid's Courant number.
        """
        if self.contact_stiffness == 0:
            zero = jnp.zeros_like(state.velocity)
            return zero, zero, _exchange(zero, pairs_none(load.pairs), load.pairs)
        pairs = load.pairs
        dt, l0 = params.dt, disc.spacing
        member = is_body(state)
        body = jnp.where(member, state.rigid.body, -1)
        partner_body = take_rows(body + 1, pairs.index) - 1
        wall = jnp.logical_and(state.active, state.kind == int(Kind.WALL))
        near = (
            pairs.valid
            & member[:, None]
            & (pairs.distance < self.contact_distance * l0)
        )
        on_wall = near & take_rows(wall, pairs.index)
        velocity = jnp.where(member[:, None], rigid_k, state.velocity)
        flat = _flat(pairs, _solids(state), outward, l0)
        normal, gap, v_wall = _wall_surface(
            on_wall, pairs, outward, velocity, l0, round_partners(state, pairs), flat
        )
        pressed = jnp.zeros_like(near)
        if self.count >= 2:  # with no pair of bodies nothing to compute
            # between bodies: each particle of the lower-index body against the
            # particles of one higher-index body (the highest it touches)
            other = jnp.max(jnp.where(near, partner_body, -1), axis=1)
            facing_body = near & (partner_body > body[:, None])
            facing_body = facing_body & (partner_body == other[:, None])
            faces = _body_faces(state, outward)
            gaps, _, _ = _pair_gaps(facing_body, pairs, faces, l0, own=True)
            pressed = facing_body & (gaps < l0)
        count = body_sum(
            ((gap < l0) | jnp.any(pressed, axis=1) | _partnered(pressed, pairs)).astype(
                mass.dtype
            )
        )
        share = jnp.where(member, (mass / jnp.maximum(count, 1.0))[body], 0.0)
        magnitude = functools.partial(
            _contact_magnitude, self.contact_stiffness, self.contact_damping, dt
        )
        v_n = jnp.sum((velocity - v_wall) * normal, axis=-1)
        push = magnitude(share, l0 - gap, v_n)
        force = jnp.where((gap < l0)[:, None], push[:, None] * normal, 0.0)
        if self.count < 2:
            zero = jnp.zeros_like(force)
            return force, zero, Exchange(zero, jnp.zeros_like(rot.cross(zero, zero)))
        own, exchange = _push_between_bodies(
            facing_body, pairs, faces, share, velocity, l0, magnitude
        )
        return force, own, exchange

    def _rub_bodies(
        self,
        disc: Discretisation,
        params: Params,
        state: State,
        load: FluidLoad,
        velocity: Float[Array, "b d"],
        momentum_l: Float[Array, "b a"],
        mass: Float[Array, " b"],
        lever: Float[Array, "n d"],
        inertia: Float[Array, "b a a"],
        between: tuple[Float[Array, "n d"], Float[Array, "n d"]],
        outward: Float[Array, "n d"],
        spare: Float[Array, " b"],
    ) -> tuple[Float[Array, "b d"], Float[Array, "b a"], Bool[Array, " b"]]:
        """Coulomb friction between bodies, particle by particle: the change of
        each body's centre-of-mass velocity and of its angular momentum about
        it, and which bodies are anchored.

        A particle i of body A with particles of a body B > A within the contact
        distance (of the highest such B) takes their mean outward normal n_i and
        the normal force N_i its partners exert on it (their pressure pair terms
        and the contact force). Its impulse J_i acts at the middle of its pairs,
        on A, and -J_i on B at the same point, so the bodies keep momentum and
        angular momentum. The impulses solve the contacts together by
        `friction_sweeps` Jacobi sweeps: each sweep takes the tangential
        velocity v_t of A relative to B at that point with the impulses so far
        and sets J_i <- J_i - m_c v_t, kept if |J_i| <= mu_s N_i dt (stick),
        otherwise scaled to mu_k N_i dt (slip); 1/m_c is the point's compliance
        along v_t on both bodies (1/M + (r x t).I^-1 (r x t)) times each body's
        number of contact particles (Jacobi's share, which keeps the sweeps from
        overshooting). With the friction torque on, the faces between the
        bodies hold them from turning over each other within the same sweeps
        (`_FacesBetween`): n_i is then the pair's mean normal, and where a face
        holds, the point's compliance counts the two bodies turning together
        ((r_B - r_A) x t with I_A + I_B) and each turning about n alone.

        A body that sticks to the walls (velocities after the wall friction)
        with a `spare` static capacity [N s] at least the most friction the
        other bodies can put on it (the sum of their mu N_i dt over its
        contacts) is anchored: it does not move in the sweeps (its partners stop
        against it with their compliance alone), and the caller hands it the
        impulses to resolve with the walls again (it stays stuck). Two anchored
        bodies rub against each other as free ones.

        # Choice: the pair's coefficients are the smaller of the two bodies'
        # (`Params.rigid.mu_static`, `mu_kinetic`): the slipperier surface rules.
        # Resolved once after the walls, at the pair's reduced mass, a block
        # resting on a base that the walls held kept a share of its load every
        # step, and both crept (a 0.5 x 0.25 m block on a 2 x 0.25 m base, tan =
        # 0.6, l0 = 0.05 m: the base 1.2 mm/s); anchoring the base stops them.
        # With the bodies' shares counted over the partners only, the top block
        # was stopped 1.3-1.5 times over and crept upslope. A stack of three
        # needs the sweeps (the middle block rubs on two bodies): with 16 its
        # blocks slid 3.8 / 5.3 mm in 1 s (27 / 60 with the contact pushing
        # along each pair), with 32 crept 0.43 / 0.97 mm, with 64 stayed within
        # 0.05 mm (validation/block_stack_sweeps.py; before the faces' couples).
        # With the bodies' rotation left out of m_c the sweeps overshot (a
        # square's side point has M / 2.5) and two blocks side by side blew up;
        # with the faces holding, so did two touching blocks side by side in
        # water (the friction's moments turn the two together, which the face
        # does not stop) until the common turning was counted.
        """
        rubbing, slots, anchored = self._body_contacts(
            disc, params, state, load, mass, lever, between, outward, spare
        )
        change, turn = self._sweep_bodies(
            rubbing, slots, anchored, velocity, momentum_l, mass, inertia, params.dt
        )
        return change, turn, anchored

    def _body_contacts(
        self,
        disc: Discretisation,
        params: Params,
        state: State,
        load: FluidLoad,
        mass: Float[Array, " b"],
        lever: Float[Array, "n d"],
        between: tuple[Float[Array, "n d"], Float[Array, "n d"]],
        outward: Float[Array, "n d"],
        spare: Float[Array, " b"],
    ) -> tuple["_Rubbing", Float[Array, " b"], Bool[Array, " b"]]:
        """`_rub_bodies`' contacts: each touching body particle's partner body,
        normal, pair middles, Coulomb caps and anchoring (gathered to the body
        particles' slots), each body's contact slots, and the anchored bodies."""
        pairs = load.pairs
        dt, l0, count = params.dt, disc.spacing, self.count
        member = is_body(state)
        body = jnp.where(member, state.rigid.body, -1)
        index = jnp.where(member, body, 0)
        partner_body = take_rows(body + 1, pairs.index) - 1
        near = (
            pairs.valid
            & member[:, None]
            & (partner_body > body[:, None])
            & (pairs.distance < self.contact_distance * l0)
        )
        # each particle rubs against one body: the highest-index one it touches
        other = jnp.max(jnp.where(near, partner_body, -1), axis=1)
        near = near & (partner_body == other[:, None])
        touching = other >= 0
        other = jnp.where(touching, other, count)
        normal, _, _ = _surface(near, pairs, outward, jnp.zeros_like(lever), l0)
        pair = jnp.where(touching, index * count + other, count * count)
        along_pair = _pair_normal(pair, touching, normal, count * count)
        pressure_force = -disc.volume * (
            0.0 if load.body_gradient is None else load.body_gradient
        )
        from_bodies, reaction = between
        n_force = jnp.sum((pressure_force + from_bodies) * along_pair, axis=-1)
        n_force = jnp.where(touching, jnp.maximum(n_force, 0.0), 0.0)
        weight = near / jnp.maximum(jnp.sum(near, axis=1, keepdims=True), 1)
        # the impulse on i and its reaction act at the middle of i's pairs:
        # `middle` from i's centre of mass, `across` from its partner's
        half = jnp.stack([jnp.sum(weight * o, axis=1) for o in pairs.offset], -1) / 2
        middle = lever + half
        across = _partner_velocity(near, pairs, lever) - half  # their mean lever
        # each body's share per contact slot: its mass over the touching
        # particles of the pairs it is in (on either side)
        in_body = jnp.where(touching, index, count)
        slots = _segment_sum(touching.astype(mass.dtype), in_body, count) + (
            _segment_sum(touching.astype(mass.dtype), other, count)
        )
        cap_s, cap_k = (
            mu * n_force * dt for mu in _pair_mu(params, near, pairs, member, index)
        )
        most = jnp.where(touching, jnp.maximum(cap_s, cap_k), 0.0)
        loads = _segment_sum(most, in_body, count) + _segment_sum(most, other, count)
        anchored = spare >= loads
        held = anchored[index] & touching
        partner_held = anchored[jnp.minimum(other, count - 1)] & touching
        both = held & partner_held

        slot = self._slots(member)
        touching = touching.at[slot].get(mode="fill", fill_value=False)

        def pick(x, fill=0):
            x = x.at[slot].get(mode="fill", fill_value=fill)
            keep = touching.reshape((-1,) + (1,) * (x.ndim - 1))
            return jnp.where(keep, x, jnp.asarray(fill, x.dtype))

        upper_key, upper_lever, upper_force = _upper_side(
            pairs,
            body,
            partner_body,
            (pairs.distance < self.contact_distance * l0) & member[:, None],
            slot,
            count,
            (lever, pressure_force + reaction),
        )
        # with the faces' couples (the friction torque on) the slip is along the
        # pair's contact plane; without them along each particle's own
        faced = self.friction is not None and self.friction.torque
        slip = along_pair if faced else normal
        picked = (slip, middle, across, cap_s, cap_k, held, partner_held, both)
        rubbing = _Rubbing(
            touching,
            pick(index),
            pick(other, count),
            *(pick(x) for x in picked),
            upper_key=upper_key,
            upper_lever=upper_lever,
            upper_force=upper_force,
        )
        return rubbing, slots, anchored

    def _slots(self, member: Bool[Array, " n"]) -> Int[Array, " m"]:
        """The particle slots the sweeps run over: those that hold body
        particles (all where `particles` is None; n marks a spare one)."""
        n = member.shape[0]
        if self.particles is None:
            return jnp.arange(n)
        return jnp.nonzero(member, size=self.particles, fill_value=n)[0]

    def _sweep_bodies(
        self,
        rubbing: "_Rubbing",
        slots: Float[Array, " b"],
        anchored: Bool[Array, " b"],
        velocity: Float[Array, "b d"],
        momentum_l: Float[Array, "b a"],
        mass: Float[Array, " b"],
        inertia: Float[Array, "b a a"],
        dt: Float[Array, ""],
    ) -> tuple[Float[Array, "b d"], Float[Array, "b a"]]:
        """`_rub_bodies`' Jacobi sweeps over the touching slots: the change of
        each body's velocity and angular momentum from the impulses and, with
        the friction torque on, the contact faces' couples (`_FacesBetween`),
        solved in the same sweeps."""
        count = self.count
        touching, index, other = rubbing.touching, rubbing.index, rubbing.other
        normal, middle, across = rubbing.normal, rubbing.middle, rubbing.across
        cap_s, cap_k, both = rubbing.cap_s, rubbing.cap_k, rubbing.both
        own_fixed = rubbing.held & ~both
        their_fixed = rubbing.partner_held & ~both
        in_body, j = jnp.where(touching, index, count), jnp.minimum(other, count - 1)
        turn_per = jnp.linalg.inv(inertia)
        free = ~anchored[:, None]
        faces = None
        if self.friction is not None and self.friction.torque:
            faces = _FacesBetween.build(rubbing, anchored, inertia, count, dt)
            together = jnp.linalg.inv(inertia[index] + inertia[j])

        def give(b, arm, t, fixed, holding):
            # the slot's compliance along t at `arm` from body b's centre of
            # mass, times the body's slots (Jacobi's share); 0 when anchored.
            # Where its face holds, the body turns about the face's normal alone
            rt = rot.cross(arm, t)
            if faces is not None:
                rt = jnp.where(holding[:, None], faces.about(rt), rt)
            k = 1.0 / mass[b] + einsum("ni,nij,nj->n", rt, turn_per[b], rt)
            return jnp.where(fixed, 0.0, slots[b] * k)

        def changes(impulse, among):
            on_i = jnp.where(among[:, None], impulse, 0.0)
            dv = _segment_sum(on_i, in_body, count) - _segment_sum(on_i, other, count)
            dl = _segment_sum(rot.cross(middle, on_i), in_body, count) - _segment_sum(
                rot.cross(across, on_i), other, count
            )
            return dv / mass[:, None], dl

        def sweep(_, carry):
            # the bodies' motion with the impulses and couples so far (an
            # anchored body moves only with those from other anchored bodies),
            # at the middle of each slot's pairs on either side
            impulse, couple, holding = carry
            pair, rest = changes(impulse, both), changes(impulse, ~both)
            v = velocity + pair[0] + jnp.where(free, rest[0], 0.0)
            ell = momentum_l + pair[1] + jnp.where(free, rest[1], 0.0)
            if faces is not None:
                ell, couple, holding = faces.sweep(ell, couple, impulse)
            omega = jnp.linalg.solve(inertia, ell[..., None])[..., 0]
            relative = (v[index] + rot.spin_cross(omega[index], middle)) - (
                v[j] + rot.spin_cross(omega[j], across)
            )
            along = jnp.sum(relative * normal, -1, keepdims=True)
            tangential = relative - along * normal
            speed = safe_norm(tangential, touching, placeholder=0.0)
            t = tangential / jnp.where(speed > 0, speed, 1.0)[:, None]
            total = give(index, middle, t, own_fixed, holding) + give(
                j, across, t, their_fixed, holding
            )
            if faces is not None:
                # where the face holds, the two turn together when both move:
                # the impulse's moment about the pair, (r_B - r_A) x t, turns
                # them with I_A + I_B
                moving = holding & ~own_fixed & ~their_fixed
                swing = rot.cross(middle - across, t)
                common = einsum("ni,nij,nj->n", swing, together[index], swing)
                share = jnp.maximum(slots[index], slots[j])
                total = total + jnp.where(moving, share * common, 0.0)
            m_c = jnp.where(total > 0, 1.0 / jnp.where(total > 0, total, 1.0), 0.0)
            trial = impulse - m_c[:, None] * tangential
            size = safe_norm(trial, touching, placeholder=0.0)
            scale = jnp.where(size > cap_s, cap_k / jnp.where(size > 0, size, 1.0), 1.0)
            impulse = jnp.where(touching[:, None], scale[:, None] * trial, 0.0)
            return impulse, couple, holding

        start = (
            jnp.zeros_like(middle),
            jnp.zeros((count * count, momentum_l.shape[-1]), momentum_l.dtype),
            jnp.zeros_like(touching),
        )
        impulse, couple, _ = jax.lax.fori_loop(0, self.friction_sweeps, sweep, start)
        change, turn = changes(impulse, touching)
        if faces is not None:
            turn = turn + faces.turn(couple, moving=False)
        return change, turn

    def _contact(
        self,
        disc: Discretisation,
        state: State,
        load: FluidLoad,
        body_sum: Callable[[Shaped[Array, "n ..."]], Shaped[Array, "b ..."]],
        arm_k: Float[Array, "n d"],
        outward: Float[Array, "n d"],
        push: Float[Array, "n d"],
    ) -> tuple[Contact, Bool[Array, " n"]]:
        """Each body's contact with walls from the pairs of the step: the force
        the walls exerted (pressure and the contact `push` on each particle), its
        moment about the contact point, the contact normal, the touching
        particles' pressure and the mean lever arm of the touching particles; and
        which particles touch."""
        pairs = load.pairs
        member = is_body(state)
        wall = jnp.logical_and(state.active, state.kind == int(Kind.WALL))
        partners = pairs.valid & member[:, None] & take_rows(wall, pairs.index)
        near = partners & (pairs.distance < self.contact_distance * disc.spacing)
        # Choice: the sum of the partners' outward normals. The sum of the unit
        # vectors from the partners tilts by up to 9 degrees with the body's offset
        # along the wall's lattice (the same way for every particle of a flat
        # face), which tilted the friction's tangent plane as a body slid.
        particle_normal = jnp.stack(
            [
                jnp.sum(jnp.where(near, take_rows(outward[:, a], pairs.index), 0.0), 1)
                for a in range(disc.dim)
            ],
            axis=-1,
        )
        particle_force = (
            jnp.where(member[:, None], -disc.volume * load.wall_gradient, 0.0) + push
        )
        force = body_sum(particle_force)
        normal_sum = body_sum(particle_normal)
        touching_p = jnp.any(particle_normal != 0, axis=-1) & member
        touching = body_sum(touching_p.astype(state.pressure.dtype)) > 0
        length = safe_norm(normal_sum, touching, placeholder=1.0)
        normal = jnp.where(touching[:, None], normal_sum / length[:, None], 0.0)
        pressure_sum = body_sum(jnp.where(touching_p, state.pressure, 0.0))
        touching_count = body_sum(touching_p.astype(state.pressure.dtype))
        per_touching = jnp.where(touching, touching_count, 1.0)[:, None]
        arm = body_sum(jnp.where(touching_p[:, None], arm_k, 0.0)) / per_touching
        moment = body_sum(rot.cross(arm_k, particle_force)) - rot.cross(arm, force)
        # The touched walls' velocity: a prescribed motion's (`move_walls` gives
        # its particles the step's mean velocity), zero for fixed walls.
        partner_velocity = jnp.stack(
            [
                _mean_over(near, take_rows(state.velocity[:, a], pairs.index))
                for a in range(disc.dim)
            ],
            axis=-1,
        )
        wall_velocity = (
            body_sum(jnp.where(touching_p[:, None], partner_velocity, 0.0))
            / per_touching
        )
        contact = Contact(
            force=force,
            normal=normal,
            touching=touching,
            pressure_sum=pressure_sum,
            arm=arm,
            wall_velocity=wall_velocity,
            moment=moment,
        )
        return contact, touching_p


def _wall_reaction(
    state: State, pairs, push: Float[Array, "n d"], reach
) -> Float[Array, "n d"]:
    """The reaction of the walls' contact `push` on each wall particle [N]: each
    body particle's push shared equally among its wall partners closer than
    `reach` (those `_push` took its surface from), with the sign turned; zero on
    other particles. Summed over all walls it is minus the push on the bodies."""
    wall = jnp.logical_and(state.active, state.kind == int(Kind.WALL))
    near = (
        pairs.valid
        & is_body(state)[:, None]
        & take_rows(wall, pairs.index)
        & (pairs.distance < reach)
    )
    return reaction_on_partners(near, pairs.index, push, push.shape[0])


def reaction_on_partners(
    close: Bool[Array, "m k"], partner: Int[Array, "m k"], force, n: int
) -> Float[Array, "n d"]:
    """Minus each of m particles' `force` (m, d), shared equally among its
    partners in `close` (slots `partner` of n), summed on each of the n slots."""
    dim = force.shape[-1]
    share = force / jnp.maximum(jnp.sum(close, axis=1), 1)[:, None]
    values = jnp.where(close[..., None], -share[:, None, :], 0.0)
    target = jnp.where(close, partner, n)
    return jax.ops.segment_sum(
        values.reshape(-1, dim), target.reshape(-1), num_segments=n + 1
    )[:n]


def _held(params: Params, time, velocity, momentum):
    """The bodies' velocity and angular momentum, zero for those held still
    before their `Params.rigid.release_time`."""
    release = params.rigid.release_time
    if release is None:
        return velocity, momentum
    held = (time < release)[:, None]
    return jnp.where(held, 0.0, velocity), jnp.where(held, 0.0, momentum)


def is_body(state: State) -> Bool[Array, " n"]:
    """Active particles that belong to a rigid body."""
    return jnp.logical_and(state.active, state.rigid.body >= 0)


class _Rubbing(eqx.Module):
    """Friction between bodies, per body-particle slot: whether it touches a
    higher body, its body and that body (count where none), the contact normal,
    the pair middles from the two centres of mass, the static and kinetic
    impulse caps, and whether its body, its partner body or both are anchored.
    Then the same slot as a particle of the upper body B of a pair A < B
    (`upper_key` A count + B, count^2 where it touches no lower body): where it
    is from B's centre of mass, and the force A puts on it [N] (pressure and
    push)."""

    touching: Bool[Array, " m"]
    index: Int[Array, " m"]
    other: Int[Array, " m"]
    normal: Float[Array, "m d"]
    middle: Float[Array, "m d"]
    across: Float[Array, "m d"]
    cap_s: Float[Array, " m"]
    cap_k: Float[Array, " m"]
    held: Bool[Array, " m"]
    partner_held: Bool[Array, " m"]
    both: Bool[Array, " m"]
    upper_key: Int[Array, " m"]
    upper_lever: Float[Array, "m d"]
    upper_force: Float[Array, "m d"]


# Jacobi sweeps of the faces' couples within each sweep of the friction: with one
# a stack of three blocks (0.5 x 0.25 m on a 2 m base, tan = 0.6 = 0.91 mu) crept
# 0.09 / 0.25 mm in 1 s, with two 0.01 / 0.035 mm, with four 0.002 / 0.005 mm
_FACE_SWEEPS = 4


class _FacesBetween(eqx.Module):
    """The contact faces between pairs of bodies (A < B, keyed A count + B):
    their normal forces stop B turning over A (every component of B's angular
    velocity relative to A's but the spin about the contact normal n) while
    their resultant stays on the face, as `_face` does against walls. The couple
    K acts on B and -K on A. With the moment M_C about the face's mean point r_C
    (the mean of the pairs' middles) that A's pressure and push already put on
    B this step, the face's total K + dt M_C is at most N dt e: N the normal
    force B feels from A (pressure, push, and the normal part of the friction's
    impulses on it), e the farthest of the pairs' middles from r_C along
    n x K / |K|. Beyond that B turns over the face's edge with the rest.

    The couples are solved within the friction's sweeps (`hold`, Jacobi: each
    body's compliance I^-1 times the number of faces it has, `_FACE_SWEEPS`
    times per sweep), and where a face holds the friction's compliance there
    has no turning but about n: the friction finds its stick impulses with the
    faces holding.

    # Choice: without these couples only the pressure and the push between the
    # two lattices held a block up on another: a block 0.3 x 0.6 m (l0 = 0.05 m)
    # on a base block toppled at 0.9 of (w - l0) / (h - l0), where on a wall it
    # stands to 0.97. Applied once after the sweeps, the couples took away the
    # rotation with which the sweeps had stopped the contact points, leaving
    # the centre's motion: resting blocks crept 4-7 mm in 2 s. N is B's side:
    # the pair form of the pressure is not antisymmetric, and on A it read
    # 0.86-0.93 of a resting block's weight (1.00 on B); with the friction
    # slipping along each particle's own normal, the friction's part of N was
    # 0.2-0.3 of the weight and growing. The face reaches to the pairs'
    # middles, half a spacing beyond the corner particles, where the two
    # lattices meet, as the friction's impulses act there: the block above
    # tips at its solid's limit tan = w / h (measured between 0.491 and 0.509
    # for w / h = 0.5); against walls `_face` takes the particles' hull
    # (w - l0) / (h - l0).
    """

    count: int = eqx.field(static=True)
    live: Bool[Array, " p"]
    normal: Float[Array, "p d"]
    moves_a: Bool[Array, " p"]
    moves_b: Bool[Array, " p"]
    stiffness: Float[Array, "p a a"]
    existing: Float[Array, "p a"]
    push: Float[Array, " p"]
    pair: Int[Array, " m"]
    middle: Float[Array, "m d"]
    reach: Float[Array, "p 2"] | None
    turn_per: Float[Array, "b a a"]

    @classmethod
    def build(cls, rubbing, anchored, inertia, count, dt) -> "_FacesBetween":
        faces = count * count
        touching = rubbing.touching
        pair = jnp.where(touching, rubbing.index * count + rubbing.other, faces)
        upper = rubbing.upper_key

        def per_pair(x, key=pair):
            keep = (key < faces).reshape((-1,) + (1,) * (x.ndim - 1))
            return _segment_sum(jnp.where(keep, x, 0.0), key, faces)

        number = per_pair(jnp.ones_like(rubbing.cap_s))
        has = number > 0
        per = jnp.where(has, number, 1.0)[:, None]
        # the face's mean point from A's centre of mass and from B's
        centre_a = per_pair(rubbing.middle) / per
        centre_b = per_pair(rubbing.across) / per
        # the partners' outward normals point from B into A
        direction = -per_pair(rubbing.normal)
        length = safe_norm(direction, has, placeholder=1.0)
        n = jnp.where(has[:, None], direction / length[:, None], 0.0)
        # what B feels from A: its normal force and its moment about the face's
        # mean point
        on_b = rubbing.upper_lever - centre_b[jnp.minimum(upper, faces - 1)]
        load = jnp.sum(per_pair(rubbing.upper_force, upper) * n, -1)
        existing = dt * per_pair(rot.cross(on_b, rubbing.upper_force), upper)
        a_body, b_body = jnp.arange(faces) // count, jnp.arange(faces) % count
        both = anchored[a_body] & anchored[b_body]
        moves_a, moves_b = ~anchored[a_body] | both, ~anchored[b_body] | both
        live = has & (moves_a | moves_b)
        shares = _segment_sum((live & moves_a).astype(n.dtype), a_body, count)
        shares = shares + _segment_sum((live & moves_b).astype(n.dtype), b_body, count)
        turn_per = shares[:, None, None] * jnp.linalg.inv(inertia)
        compliance = jnp.where(moves_a[:, None, None], turn_per[a_body], 0.0)
        compliance = compliance + jnp.where(
            moves_b[:, None, None], turn_per[b_body], 0.0
        )
        if n.shape[-1] == 3:  # in the plane normal to n (n n^T keeps it invertible)
            across = jnp.eye(3, dtype=n.dtype)[None] - n[:, :, None] * n[:, None, :]
            compliance = matmul(matmul(across, compliance), across) + (
                n[:, :, None] * n[:, None, :]
            )
            existing = existing - jnp.sum(existing * n, -1, keepdims=True) * n
        eye = jnp.eye(compliance.shape[-1], dtype=n.dtype)
        compliance = jnp.where(live[:, None, None], compliance, eye)
        middle = rubbing.middle - centre_a[jnp.minimum(pair, faces - 1)]
        reach = None
        if n.shape[-1] == 2:  # the lever is +-(n_y, -n_x)
            lever = jnp.stack([n[:, 1], -n[:, 0]], axis=-1)
            reach = jnp.stack(
                [_face_reach(middle, pair, lever), _face_reach(middle, pair, -lever)],
                axis=-1,
            )
        return cls(
            count=count,
            live=live,
            normal=n,
            moves_a=moves_a,
            moves_b=moves_b,
            stiffness=jnp.linalg.inv(compliance),
            existing=existing,
            push=dt * load,
            pair=pair,
            middle=middle,
            reach=reach,
            turn_per=jnp.linalg.inv(inertia),
        )

    def _ends(self):
        faces = self.count * self.count
        return jnp.arange(faces) // self.count, jnp.arange(faces) % self.count

    def turn(self, couple: Float[Array, "p a"], moving: bool) -> Float[Array, "b a"]:
        """Each body's change of angular momentum from the couples (`moving`:
        only the bodies the sweeps move)."""
        a_body, b_body = self._ends()
        on_b, on_a = self.live, self.live
        if moving:
            on_b, on_a = on_b & self.moves_b, on_a & self.moves_a
        return _segment_sum(
            jnp.where(on_b[:, None], couple, 0.0), b_body, self.count
        ) - _segment_sum(jnp.where(on_a[:, None], couple, 0.0), a_body, self.count)

    def sweep(
        self,
        momentum_l: Float[Array, "b a"],
        couple: Float[Array, "p a"],
        impulse: Float[Array, "m d"],
    ) -> tuple[Float[Array, "b a"], Float[Array, "p a"], Bool[Array, " m"]]:
        """`_FACE_SWEEPS` sweeps of the couples within one of the friction's:
        the bodies' angular momentum (without the couples so far) and the
        couples after them, and which slots' faces hold."""
        most = self.limit(impulse)

        def face_sweep(_, held):
            ell, couple, _ = held
            more, holds = self.hold(ell, couple, most)
            return ell + self.turn(more - couple, moving=True), more, holds

        start = (momentum_l + self.turn(couple, moving=True), couple, self.live)
        ell, couple, holds = jax.lax.fori_loop(0, _FACE_SWEEPS, face_sweep, start)
        return ell, couple, self.holding(holds)

    def limit(self, impulse: Float[Array, "m d"]) -> Float[Array, " p"]:
        """N dt per face with the friction's `impulse` so far: their parts along n
        on B (-J at each slot) count with the pressure and the push."""
        faces = self.count * self.count
        n = self.normal[jnp.minimum(self.pair, faces - 1)]
        pressing = jnp.where(self.pair < faces, jnp.sum(impulse * n, -1), 0.0)
        return jnp.maximum(self.push - _segment_sum(pressing, self.pair, faces), 0.0)

    def hold(
        self,
        momentum_l: Float[Array, "b a"],
        couple: Float[Array, "p a"],
        most: Float[Array, " p"],
    ) -> tuple[Float[Array, "p a"], Bool[Array, " p"]]:
        """The couples after one sweep: those so far (included in `momentum_l`)
        and what stops the relative turning that remains, each face's total at
        most `most` (N dt) times its reach; and which faces hold."""
        a_body, b_body = self._ends()
        n = self.normal
        omega = einsum("bij,bj->bi", self.turn_per, momentum_l)
        relative = omega[b_body] - omega[a_body]
        dim = n.shape[-1]
        if dim == 3:  # the spin about the normal is free
            relative = relative - jnp.sum(relative * n, -1, keepdims=True) * n
        total = couple - einsum("pij,pj->pi", self.stiffness, relative)
        total = total + self.existing
        if dim == 3:  # normal forces give no moment about the normal
            total = total - jnp.sum(total * n, -1, keepdims=True) * n
        size = safe_norm(total, self.live, placeholder=0.0)
        if dim == 2:
            e = jnp.where(total[:, 0] > 0, self.reach[:, 0], self.reach[:, 1])
        else:
            unit = total / jnp.where(size > 0, size, 1.0)[:, None]
            e = _face_reach(self.middle, self.pair, jnp.cross(n, unit))
        scale = jnp.minimum(1.0, most * e / jnp.where(size > 0, size, 1.0))
        held = jnp.where(self.live[:, None], scale[:, None] * total - self.existing, 0)
        return held, self.live & (scale >= 1.0)

    def holding(self, holds: Bool[Array, " p"]) -> Bool[Array, " m"]:
        """Which slots' faces hold."""
        faces = self.count * self.count
        return holds[jnp.minimum(self.pair, faces - 1)] & (self.pair < faces)

    def about(self, moment: Float[Array, "m a"]) -> Float[Array, "m a"]:
        """Each slot's `moment` about its face's normal alone (0 in 2-D)."""
        if moment.shape[-1] == 1:
            return jnp.zeros_like(moment)
        n = self.normal[jnp.minimum(self.pair, self.count * self.count - 1)]
        return jnp.sum(moment * n, -1, keepdims=True) * n


def _pair_mu(params: Params, near, pairs, member, index):
    """Each body particle's static and kinetic coefficients against the body it
    touches (`near` its partners there): the smaller of the two bodies'."""
    for mu in (params.rigid.mu_static, params.rigid.mu_kinetic):
        partner = take_rows(jnp.where(member, mu[index], 0.0), pairs.index)
        yield jnp.minimum(mu[index], _mean_over(near, partner))


def _upper_side(pairs, body, partner_body, close, slot, count, values):
    """Each body-particle slot as a particle of the upper body B of a pair A < B
    (A the highest lower-index body it touches, `close` the pairs in contact
    distance): the pair's key A count + B (count^2 where it touches no lower
    body) and `values` (per particle) at the slots, 0 where none."""
    below = pairs.valid & close & (partner_body >= 0) & (partner_body < body[:, None])
    lower = jnp.max(jnp.where(below, partner_body, -1), axis=1)
    resting = (lower >= 0).at[slot].get(mode="fill", fill_value=False)
    key = jnp.where(lower >= 0, lower * count + body, count * count)
    key = key.at[slot].get(mode="fill", fill_value=count * count)
    picked = (
        jnp.where(resting[:, None], x.at[slot].get(mode="fill", fill_value=0), 0.0)
        for x in values
    )
    return jnp.where(resting, key, count * count), *picked


def _face_reach(middle, pair, lever):
    """The farthest of each face's pair middles from its mean point along its
    `lever` (0 where none reaches out that way)."""
    faces = lever.shape[0]
    along = jnp.sum(middle * lever[jnp.minimum(pair, faces - 1)], axis=-1)
    farthest = jax.ops.segment_max(along, pair, num_segments=faces + 1)[:faces]
    return jnp.maximum(farthest, 0.0)


class Exchange(eqx.Module):
    """Forces (or impulses) between bodies with their reactions: per particle the
    total, and the moment about the particle that acting at the pairs' middles
    adds (so that their sum keeps angular momentum)."""

    total: Float[Array, "n d"]
    moment: Float[Array, "n a"]


def pairs_none(pairs) -> Bool[Array, "n k"]:
    return jnp.zeros_like(pairs.valid)


def _partnered(mask: Bool[Array, "n k"], pairs) -> Bool[Array, " n"]:
    """Particles that are the partner j of some pair (i, j) in `mask`."""
    n = mask.shape[0]
    hits = jax.ops.segment_sum(
        mask.reshape(-1).astype(jnp.int32), pairs.index.reshape(-1), n + 1
    )
    return hits[:n] > 0


def _exchange(own: Float[Array, "n d"], mask: Bool[Array, "n k"], pairs) -> Exchange:
    """`own` on each particle i, and -own shared equally among its partners j in
    `mask`, each share acting with its own at the middle of the pair."""
    n, dim = own.shape
    weight = mask / jnp.maximum(jnp.sum(mask, axis=1, keepdims=True), 1)
    back = -weight[..., None] * own[:, None, :]  # (n, k, d), on j
    half = jnp.stack([0.5 * o for o in pairs.offset], axis=-1)  # (r_j - r_i) / 2
    flat = pairs.index.reshape(-1)
    back_total = jax.ops.segment_sum(back.reshape(-1, dim), flat, n + 1)[:n]
    # j's share acts at r_j - (r_j - r_i) / 2; i's force at r_i + (r_j - r_i) / 2
    back_moment = jax.ops.segment_sum(
        rot.cross(-half, back).reshape(n * mask.shape[1], -1), flat, n + 1
    )[:n]
    own_moment = rot.cross(jnp.sum(weight[..., None] * half, axis=1), own)
    return Exchange(total=own + back_total, moment=own_moment + back_moment)


def _mean_over(mask: Bool[Array, "n k"], values: Float[Array, "n k"]):
    """Mean of `values` over the slots in `mask` (0 where none)."""
    total = jnp.sum(jnp.where(mask, values, 0.0), axis=1)
    return total / jnp.maximum(jnp.sum(mask, axis=1), 1)


def round_partners(state: State, pairs) -> Bool[Array, "n k"] | None:
    """Which neighbour slots hold a grain (`State.grains`; None without
    grains): spheres, whose contact with a body goes by their distance."""
    if state.grains is None:
        return None
    grain = jnp.zeros(state.position.shape[:1], bool).at[state.grains.index].set(True)
    return take_rows(grain, pairs.index)


def _solids(state: State) -> Int[Array, " n"]:
    """Each particle's solid: walls and dummies 0, rigid body b b + 1, else -1."""
    solid = state.active & (
        (state.kind == int(Kind.WALL)) | (state.kind == int(Kind.DUMMY))
    )
    member = is_body(state)
    return jnp.where(solid, 0, jnp.where(member, state.rigid.body + 1, -1))


def _same_group(pairs, group: Int[Array, " n"]) -> Bool[Array, "n k"]:
    """Which partners belong to the particle's own `group` (-1: none)."""
    return (take_rows(group + 1, pairs.index) - 1 == group[:, None]) & (
        group[:, None] >= 0
    )


def _outward(pairs, group: Int[Array, " n"]) -> Float[Array, "n d"]:
    """Each particle's outward unit normal from the particles of its own `group`
    (-1: none): minus the sum of the unit vectors towards them (zero inside a
    solid, where they cancel). A straight wall's particles all get its normal."""
    own = _same_group(pairs, group)
    inward = pair_sum(
        jnp.where(own & pairs.valid, 1.0 / pairs.distance, 0.0), pairs.offset
    )
    length = safe_norm(inward, jnp.ones(inward.shape[0], bool))
    return -inward / length[:, None]


def _surface(close: Bool[Array, "n k"], pairs, outward, velocity, l0):
    """The surface that the partners in `close` present to each particle: the
    mean of their outward normals, the gap along it (2 l0 where none), and the
    partners' mean velocity."""
    normal_sum = jnp.stack(
        [
            _mean_over(close, take_rows(outward[:, a], pairs.index))
            for a in range(outward.shape[-1])
        ],
        axis=-1,
    )
    any_close = jnp.any(close, axis=1)
    ok = any_close & jnp.any(normal_sum != 0, axis=-1)
    length = safe_norm(normal_sum, ok)
    normal = jnp.where(ok[:, None], normal_sum / length[:, None], 0.0)
    along = -sum(o * normal[:, a, None] for a, o in enumerate(pairs.offset))
    gap = jnp.min(jnp.where(close, along, 2.0 * l0), axis=1)
    gap = jnp.where(ok, gap, 2.0 * l0)
    return normal, gap, _partner_velocity(close, pairs, velocity)


def _partner_velocity(close, pairs, velocity):
    return jnp.stack(
        [
            _mean_over(close, take_rows(velocity[:, a], pairs.index))
            for a in range(velocity.shape[-1])
        ],
        axis=-1,
    )


# A wall partner faces a body particle where the particle lies within this angle
# of the partner's (lattice) normal: cos 41 degrees, short of the 45 degrees of a
# flat wall's diagonal neighbours and of an edge particle beside the particle.
_FACING = 0.75
# Between bodies the plane's gap holds fully within 30 degrees of the normal
# (beyond the 26.6 degrees of a flat face's nearest partner on the lattice).
_FACED = math.cos(math.radians(30.0))


def _contact_magnitude(kappa, zeta, dt, m_c, depth, v_n):
    """The contact's spring-dashpot force magnitude [N], never pulling: stiffness
    kappa m_c / dt^2, damping 2 zeta sqrt(kappa) m_c / dt (see `RigidBodies._push`)."""
    spring = kappa * m_c / dt**2 * depth
    return jnp.maximum(spring - 2 * zeta * jnp.sqrt(kappa) * m_c / dt * v_n, 0)


def _push_between_bodies(close, pairs, faces, share, velocity, l0, magnitude):
    """The contact force between bodies on the particles of the lower-index body
    of each contact (`close`: its partners in the other body), and that exchange
    with the partners' reactions, shared among the partners closer than l0 and
    acting at the pairs' middles.

    The other body is a surface to the particle, as a wall is (`_pair_gaps`):
    each partner's gap is its distance from the plane of the flatter of the two
    particles' faces, so that a flat face sliding on another meets no bumps of
    the lattice.

    # Choice: a push along each pair (central) made the lattice a washboard: a
    # 0.5 x 0.25 m block sliding frictionless down another at l0 = 0.05 m
    # (tan 0.6) hopped by 0.2 m/s, rocked at 1.5 rad/s and met a drag of
    # 16 % of its drive, 0.88 of the distance in 0.5 s (0.78 with mu = 0.3).
    """
    gaps, direction, facing = _pair_gaps(close, pairs, faces, l0, own=True)
    normal, gap = _contact_normal(close, gaps, direction, facing, l0)
    pressed = close & (gaps < l0)
    theirs = _mean_over(pressed, take_rows(share, pairs.index))
    m_c = share * theirs / jnp.maximum(share + theirs, 1e-300)
    v_n = jnp.sum(
        (velocity - _partner_velocity(pressed, pairs, velocity)) * normal, axis=-1
    )
    push = jnp.where(gap < l0, magnitude(m_c, l0 - gap, v_n), 0.0)
    own = push[:, None] * normal
    return own, _exchange(own, pressed, pairs)


def _pair_gaps(close, pairs, faces, l0, round_partner=None, own=False):
    """Per pair in `close`, the gap between particle i and its partner j, the
    direction (unit, towards i) a push on i takes, and whether a face sets the
    gap (else the distance does). `faces`: each particle's outward normal
    snapped to a lattice direction (`_snap`, `_body_faces`).

    A partner faces the particle where the particle lies within 41 degrees of
    the partner's face normal; its gap is then the particle's distance from the
    partner's plane, otherwise (an edge or corner beside the particle) their
    distance. A partner in `round_partner` never faces: its gap is the
    distance.

    With `own` (two bodies meeting) the particle's own face counts alike, and
    the larger of the two gaps is taken: a corner of j passing over i's flat
    face is as far as the face says, not as the corner's diagonal plane would
    put it. And the plane's gap fades into the distance between 30 and 41
    degrees off the normal, so that a pair turning into a face's cone is not
    pushed at once by a step of the gap (a rotating corner's step did work:
    two free blocks spinning past each other gained 30 % of their energy).
    """
    dim = faces.shape[-1]
    distance = jnp.where(close, pairs.distance, 2.0 * l0)
    away = [-o / distance for o in pairs.offset]  # from the partner to i

    def seen_from(normal):
        """Gap, direction and facing as a face of normal `normal` (towards i)
        sees the pair."""
        plane = -sum(o * n for o, n in zip(pairs.offset, normal))
        facing = close & (plane > _FACING * distance)
        if round_partner is not None:
            facing = facing & ~round_partner
        if not own:
            gap = jnp.where(facing, plane, distance)
            return gap, [jnp.where(facing, n, u) for n, u in zip(normal, away)], facing
        cosine = plane / distance
        weight = jnp.where(
            facing, jnp.clip((cosine - _FACING) / (_FACED - _FACING), 0.0, 1.0), 0.0
        )
        gap = distance - weight * (distance - plane)
        return gap, [u + weight * (n - u) for n, u in zip(normal, away)], facing

    theirs = [take_rows(faces[:, a], pairs.index) for a in range(dim)]
    gaps, direction, facing = seen_from(theirs)
    if own:
        mine = [-faces[:, a, None] for a in range(dim)]  # i's face, towards i
        gaps_i, direction_i, facing_i = seen_from(mine)
        wider = gaps_i > gaps
        direction = [jnp.where(wider, d_i, d) for d_i, d in zip(direction_i, direction)]
        length = safe_norm(
            jnp.stack(direction, -1).reshape(-1, dim), jnp.ones(distance.size, bool)
        ).reshape(distance.shape)
        direction = [d / length for d in direction]
        facing = jnp.where(wider, facing_i, facing)
        gaps = jnp.maximum(gaps, gaps_i)
    return gaps, direction, facing


def _body_faces(state: State, outward: Float[Array, "n d"]) -> Float[Array, "n d"]:
    """Each particle's outward normal snapped to a lattice direction of its own
    solid: a body's in its body frame (its particles were laid on a lattice
    there), the walls' in the world's."""
    dim = outward.shape[-1]
    member = is_body(state)
    index = jnp.where(member, state.rigid.body, 0)
    rotation = rot.matrix(state.rigid.orientation, dim)[index]
    local = _snap(einsum("nji,nj->ni", rotation, outward))
    faces = einsum("nij,nj->ni", rotation, local)
    return jnp.where(member[:, None], faces, _snap(outward))


def _contact_normal(close, gaps, direction, facing, l0):
    """A particle's contact normal and gap from its partners' (`_pair_gaps`):
    the gap is the least; the normal is the mean of the directions of the
    partners closer than l0 weighted by how much closer, or, where none is, of
    the facing partners' directions."""
    depth = jnp.where(close, jnp.maximum(l0 - gaps, 0.0), 0.0)
    pressed = jnp.stack([jnp.sum(depth * d, axis=1) for d in direction], axis=-1)
    faced = jnp.stack(
        [jnp.sum(jnp.where(facing, d, 0.0), axis=1) for d in direction], axis=-1
    )
    normal_sum = jnp.where(jnp.any(depth > 0, axis=1)[:, None], pressed, faced)
    ok = jnp.any(close, axis=1) & jnp.any(normal_sum != 0, axis=-1)
    length = safe_norm(normal_sum, ok)
    normal = jnp.where(ok[:, None], normal_sum / length[:, None], 0.0)
    gap = jnp.where(ok, jnp.min(jnp.where(close, gaps, 2.0 * l0), axis=1), 2.0 * l0)
    return normal, gap


def _wall_surface(
    close: Bool[Array, "n k"],
    pairs,
    outward,
    velocity,
    l0,
    round_partner=None,
    flat=None,
):
    """The wall surface that the partners in `close` present to each body
    particle for the contact push: a normal, the gap (2 l0 where none) and the
    partners' mean velocity.

    Each partner's outward normal is snapped to the nearest lattice direction
    (the axes and diagonals) and the partners' gaps taken from their faces
    (`_pair_gaps`); a partner in `round_partner` (a grain attached to the bed:
    a sphere, off the lattice) never faces, nor does one that is not `flat`
    (`_flat`, per particle: a convex corner or edge is a point). The gap and
    normal are the partners' (`_contact_normal`).

    # Choice: the gap along the mean normal of all partners took the recess a
    # block rests in (a concave corner: diagonal mean normal, the floor partner
    # l0 / sqrt(2) along it) and the lip of a scour hole beside a block (an edge
    # particle level with the block's, its normal pointing away) for overlaps of
    # 0.1-0.3 l0, and the push, stiff as 1/dt^2, lifted and spun a block resting
    # in a recess (65-330 N/m semi-implicit, 4600 N/m explicit, against its 4.9
    # N/m weight). A wall particle near a corner has a normal tilted by up to 14
    # degrees (its neighbourhood holds the corner), hence the snapping. On a flat
    # wall the plane distance is the height above it whatever the offset along
    # it, as the mean normal's was (no lattice bumps while sliding); an edge is a
    # point, whose distance is the pair's. A grain is a sphere: the planes of a
    # packed bed's grains, whose normals lean with the packing, put a block's
    # corner 0.64 l0 from a grain 1.004 l0 away, and its push, held until the
    # block's release (400-1200 N/m against a 5.6 N/m weight), threw the block
    # off the bed on release.
    """
    if flat is not None:
        point = ~take_rows(flat, pairs.index)
        round_partner = point if round_partner is None else round_partner | point
    gaps, direction, facing = _pair_gaps(
        close, pairs, _snap(outward), l0, round_partner
    )
    normal, gap = _contact_normal(close, gaps, direction, facing, l0)
    return normal, gap, _partner_velocity(close, pairs, velocity)


def _flat(pairs, group: Int[Array, " n"], outward, l0) -> Bool[Array, " n"]:
    """Whether each particle's snapped face (`_snap(outward)`) is a plane of its
    solid (`group`, -1: none): it has at least 2 (d - 1) neighbours of its own
    solid within 1.5 l0 and within 0.5 l0 of that plane, as on a flat face of
    the lattice (2 in 2-D, 8 in 3-D) or a 45-degree staircase (2; 4). A convex
    corner (none) or, in 3-D, an edge (2) is not.

    # Choice: a convex corner's snapped normal is the diagonal, and its plane
    # a chamfer that cuts the corner: a ship's side passing a quay's crest 1.0
    # l0 from the crest particle, 40 degrees off that diagonal, lay 0.76 l0
    # from the chamfer, and the push (stiff as 1/dt^2 on the one particle in
    # contact) threw the ship back in one step (6 m/s, 75 times its weight); a
    # block falling past a step's corner was thrown sideways alike. A corner is
    # a point: its gap is the distance.
    """
    dim = outward.shape[-1]
    face = _snap(outward)
    own = _same_group(pairs, group)
    across = sum(o * face[:, a, None] for a, o in enumerate(pairs.offset))
    in_plane = (
        own & pairs.valid & (pairs.distance < 1.5 * l0) & (jnp.abs(across) < 0.5 * l0)
    )
    # written out: its partners read it, which would recompute the row per pair
    return materialised(jnp.sum(in_plane, axis=1) >= 2 * (dim - 1))


def _snap(normal: Float[Array, "n d"]) -> Float[Array, "n d"]:
    """Each unit vector's nearest lattice direction (components in {-1, 0, 1},
    normalised; zero stays zero)."""
    dim = normal.shape[-1]
    steps = np.array(
        [v for v in itertools.product((-1, 0, 1), repeat=dim) if any(v)], float
    )
    steps /= np.linalg.norm(steps, axis=1, keepdims=True)
    best = jnp.argmax(matmul(normal, jnp.asarray(steps, normal.dtype).T), axis=-1)
    nonzero = jnp.any(normal != 0, axis=-1, keepdims=True)
    return jnp.where(nonzero, jnp.asarray(steps, normal.dtype)[best], 0.0)


def _reach(
    touching: Bool[Array, " n"],
    index: Int[Array, " n"],
    relative: Float[Array, "n d"],
    count: int,
    direction: Float[Array, "b d"],
) -> Float[Array, " b"]:
    """Per body, the farthest of its touching particles from their mean
    (`relative`: each particle's offset from it) along `direction` (0 where
    none reaches out that way)."""
    along = jnp.sum(relative * direction[index], axis=-1)
    segment = jnp.where(touching, index, count)
    farthest = jax.ops.segment_max(along, segment, num_segments=count + 1)[:count]
    return jnp.maximum(farthest, 0.0)


def _world(inertia: Float[Array, "b a a"], rotation, dim: int):
    if dim == 2:
        return inertia
    return matmul(matmul(rotation, inertia), jnp.swapaxes(rotation, -1, -2))


def _pair_normal(pair, touching, normal, slots):
    """Each touching particle's contact normal replaced by the mean of those of
    its pair of bodies (`pair`: the pair's key, `slots` where none): the
    direction along which the friction's cap counts its normal force.

    # Choice: two convex bodies touch along one face. Per particle, the one at
    # the edge of a flat contact meets the partner's corner, whose outward
    # normal leans 45 degrees (55 at a 3-D corner), and counted cos 45 of its
    # load: the friction between bodies saw 0.90-0.93 of the normal force in
    # 3-D (a 0.4 x 0.4 x 0.2 m block, l0 = 0.1 m; 0.95-0.97 in 2-D) and let a
    # block slide 1.12 times as far as g (sin - mu cos) (validation/
    # block_slide.py). With the faces' couples (`_FacesBetween`) it is also
    # the slip's plane: along each particle's own normal the friction at those
    # edge slots carried normal load (held up a resting block in part, and
    # with the spin-up's mu = 1e3 all of it, so that it fell onto the push
    # when released). Without the couples the sweeps keep each particle's own
    # normal: with the pair's a stack of three blocks jumped 0.4 mm upslope
    # when released. Bodies that touch at several places along different
    # normals get their mean.
    """
    total = _segment_sum(jnp.where(touching[:, None], normal, 0.0), pair, slots)
    size = safe_norm(total, jnp.any(total != 0, axis=-1))  # no NaN gradient at 0
    mean = total / size[:, None]
    return jnp.where(touching[:, None], mean[jnp.minimum(pair, slots - 1)], 0.0)


def _segment_sum(values, segment, count):
    return jax.ops.segment_sum(values, segment, num_segments=count + 1)[:count]
