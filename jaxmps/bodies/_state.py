"""The rigid-body sub-state carried in `State.rigid` (arrays only)."""

import equinox as eqx
from jaxtyping import Array, Bool, Float, Int


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
        contact_force: part of `force` exerted through pressure by walls and other
            bodies (the contact reaction), shape (b, d).
        impulse: time integral of `force` since the start [N s], shape (b, d).
        angular_impulse: time integral of `torque` since the start, shape (b, a).
        friction: friction force of the last step, shape (b, d).
        sliding: whether the body was in contact and sliding in the last step, (b,).
        particle_contact: per particle, the pressure force from contact partners in
            the current step (written by the fluid solver, read by the body stage).
        particle_normal: per particle, the sum of w_ij times the unit vector from
            each contact partner j to i within the contact distance.
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
    particle_contact: Float[Array, "n d"]
    particle_normal: Float[Array, "n d"]
