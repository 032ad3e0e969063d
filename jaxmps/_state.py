"""State: the evolving arrays of a simulation, exactly the scan carry.

The sub-states of the body models live here too (as the Params of every component
live in `_params`), so that every stage can take the `State` it advances.
"""

import equinox as eqx
from jaxtyping import Array, Bool, Float, Int

from ._result import Result
from .neighbours import NeighbourCache


class RigidState(eqx.Module):
    """Rigid bodies' part of the scan carry. `b` bodies; `q` orientation components
    (1: an angle in 2-D, 4: a unit quaternion w, x, y, z in 3-D); `a` angular
    components (1 in 2-D, about z; 3 in 3-D).

    Attributes:
        body: body index of each particle slot, -1 if it belongs to none, shape (n,).
        reference: each body particle's offset from its body's centre in the body
            frame (zero orientation) [m], shape (n, d). Positions are rebuilt from it
            every step, so a body's shape never drifts.
        centre: centre of mass [m], shape (b, d).
        orientation: orientation, shape (b, q).
        velocity: centre velocity [m/s], shape (b, d).
        angular_velocity: angular velocity [rad/s], shape (b, a).
        force: force on the body in the last step, gravity excluded (fluid pressure
            and viscosity, contact and friction) [N, or N/m in 2-D], shape (b, d).
        torque: torque about the centre in the last step [N m], shape (b, a).
        contact_force: part of `force` exerted through pressure by walls (the
            contact reaction), shape (b, d).
        impulse: time integral of `force` since the start [N s], shape (b, d).
        angular_impulse: time integral of `torque` since the start, shape (b, a).
        friction: friction force of the last step, shape (b, d).
        sliding: whether the body was in contact and sliding in the last step, (b,).
        wall_push: the contact push (`RigidBodies._push`) that the bodies exerted on
            each wall particle in the last step, its reaction shared equally among
            the wall partners of each pushed body particle [N, or N/m in 2-D],
            zero on other particles, shape (n, d). What a wall carries beyond its
            pressure (`WallForce` adds it).
    """

    body: Int[Array, " n"]
    reference: Float[Array, "n d"]
    centre: Float[Array, "b d"]
    orientation: Float[Array, "b q"]
    velocity: Float[Array, "b d"]
    angular_velocity: Float[Array, "b a"]
    force: Float[Array, "b d"]
    torque: Float[Array, "b a"]
    contact_force: Float[Array, "b d"]
    impulse: Float[Array, "b d"]
    angular_impulse: Float[Array, "b a"]
    friction: Float[Array, "b d"]
    sliding: Bool[Array, " b"]
    wall_push: Float[Array, "n d"]


class ElasticState(eqx.Module):
    """Elastic bodies' part of the scan carry, over their m particles (clamped ones
    included); `k` reference neighbour slots; `q` orientation components (an
    angle in 2-D, a unit quaternion w, x, y, z in 3-D), `a` spin components.

    Attributes:
        index: each elastic particle's slot in the State, shape (m,).
        body: its body, 0..b-1, shape (m,).
        reference: its unstrained position [m], shape (m, d).
        neighbours: its reference neighbours (those within r_e in the unstrained
            body, its own body only), as elastic particle numbers, m for an empty
            slot, shape (m, k). Fixed for the run.
        clamped: whether it is held at its reference position, shape (m,).
        position, velocity: at the end of the last step [m, m/s], shape (m, d).
        rotation: its rotation, shape (m, q).
        angular_velocity: its spin [rad/s], shape (m, a).
        elastic_pressure: its elastic pressure -lambda eps_vol in the last step
            [Pa], shape (m,).
        contact_force: the mean force the walls' contact push exerted on it in
            the last step [N] (zero unless `ElasticBodies.contact` is "push"),
            shape (m, d).
        wall_push: that push's reaction on each wall particle, shared equally
            among the wall partners of each pushed particle [N], zero on other
            particles, shape (n, d) (as `RigidState.wall_push`).
    """

    index: Int[Array, " m"]
    body: Int[Array, " m"]
    reference: Float[Array, "m d"]
    neighbours: Int[Array, "m k"]
    clamped: Bool[Array, " m"]
    position: Float[Array, "m d"]
    velocity: Float[Array, "m d"]
    rotation: Float[Array, "m q"]
    angular_velocity: Float[Array, "m a"]
    elastic_pressure: Float[Array, " m"]
    contact_force: Float[Array, "m d"]
    wall_push: Float[Array, "n d"]


class GrainState(eqx.Module):
    """The DEM grains' part of the scan carry, over their m grains; `w` wall
    particles they can touch, `k` contact slots per grain; `a` spin components (1
    in 2-D, 3 in 3-D). A contact partner is numbered in the DEM set: the grains
    0..m-1, then the walls m..m+w-1; m+w marks an empty slot.

    Attributes:
        index: each grain's slot in the State, shape (m,).
        walls: the State slots of the other solid particles grains touch (walls,
            rigid and elastic bodies' particles), shape (w,).
        diameter: each grain's diameter [m], shape (m,).
        partner: each grain's contact candidates (those within the contact
            distance and a skin at the step's start), shape (m, k).
        shear: the tangential spring displacement of each slot's contact [m],
            one (m, k) array per axis, shape (d, m, k); zero where not touching.
        spin: each grain's angular velocity [rad/s], shape (m, a).
        fluid_force: the drag and lift on each grain in the last step [N],
            shape (m, d).
        contact_count: each grain's contacts at the end of the last step, (m,).
        reaction: the force per unit volume the grains exerted in the last step
            on every particle [N/m^3] (their contacts on walls and bodies, their
            drag and lift on the fluid where they push it back), which the next
            step's prediction applies, shape (n, d); (0, d) where the grains act
            on nothing (`Grains.reacts`).
        attached: whether each grain is still in the bed, a wall to the fluid
            (`Grains.bed`; False once it has detached), shape (m,).
        origin: where each grain started [m] (its detachment is measured from
            there), shape (m, d).
    """

    index: Int[Array, " m"]
    walls: Int[Array, " w"]
    diameter: Float[Array, " m"]
    partner: Int[Array, "m k"]
    shear: Float[Array, "d m k"]
    spin: Float[Array, "m a"]
    fluid_force: Float[Array, "m d"]
    contact_count: Int[Array, " m"]
    reaction: Float[Array, "r d"]
    attached: Bool[Array, " m"]
    origin: Float[Array, "m d"]


class State(eqx.Module):
    """Fixed-capacity particle state. Arrays only; its structure never changes.

    Attributes:
        time: simulated time [s].
        step: number of steps taken.
        dt: the last step's dt [s] (0 before the first).
        acceleration: the largest |du/dt| of a fluid or body particle over the
            last step [m/s^2] (0 before the first); adaptive steps read it
            (`jaxmps.Adaptive`, the force limit).
        escaped: fluid particles that left the domain box and were taken out of
            the run (made inactive), up to `Scene.escape_limit`.
        position: particle positions [m], shape (n, d).
        velocity: particle velocities [m/s], shape (n, d).
        pressure: particle pressures [Pa] (gauge; 0 on the free surface), shape (n,).
        kind: particle kind, a `jaxmps.Kind` value, shape (n,).
        active: whether the slot holds a live particle, shape (n,). Inactive slots are
            the pool: they are masked out of every sum and every neighbour search.
        result: the first failure of the run so far, or `Result.successful`.
        rigid: the rigid bodies' sub-state, present exactly when the Scene has
            rigid bodies.
        elastic: the elastic bodies' sub-state, present exactly when the Scene
            has elastic bodies.
        grains: the DEM grains' sub-state, present exactly when the Scene has
            grains.
        neighbours: the neighbour lists carried to the next step, or None (a new
            search at the start of every step). `simulate` adds it for the rollout
            (when `Scene.neighbour_skin` > 0) and removes it from what it returns
            and observes; `jaxmps.with_neighbour_lists` adds it for a loop of
            `jaxmps.step`.
    """

    time: Float[Array, ""]
    step: Int[Array, ""]
    dt: Float[Array, ""]
    acceleration: Float[Array, ""]
    escaped: Int[Array, ""]
    position: Float[Array, "n d"]
    velocity: Float[Array, "n d"]
    pressure: Float[Array, " n"]
    kind: Int[Array, " n"]
    active: Bool[Array, " n"]
    result: Result
    rigid: RigidState | None = None
    elastic: ElasticState | None = None
    grains: GrainState | None = None
    neighbours: NeighbourCache | None = None
