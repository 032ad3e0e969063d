"""Rotations of rigid bodies: an angle in 2-D, a unit quaternion (w, x, y, z) in 3-D.

Angular quantities (angular velocity, angular momentum, torque) have one component
(about z) in 2-D and three in 3-D; `spin_size(dim)` gives that count.
"""

import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import safe_norm


def spin_size(dim: int) -> int:
    """Components of an angular quantity: 1 in 2-D, 3 in 3-D."""
    return 1 if dim == 2 else 3


def orientation_size(dim: int) -> int:
    """Components of an orientation: an angle in 2-D, a quaternion in 3-D."""
    return 1 if dim == 2 else 4


def identity(dim: int, count: int, dtype) -> Float[Array, "b q"]:
    """`count` unrotated orientations."""
    if dim == 2:
        return jnp.zeros((count, 1), dtype)
    return jnp.zeros((count, 4), dtype).at[:, 0].set(1.0)


def quaternion_multiply(p: Float[Array, "*#b 4"], q: Float[Array, "*#b 4"]):
    """Hamilton product p q: scalar part p_w q_w - p_v . q_v (the digest's erratum)."""
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - jnp.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + jnp.cross(pv, qv)
    return jnp.concatenate([w, v], axis=-1)


def quaternion_from_rotation_vector(
    theta: Float[Array, "*#b 3"],
) -> Float[Array, "*#b 4"]:
    """The unit quaternion of a rotation by |theta| about theta/|theta| (Rodrigues).

    Finite value and gradient at theta = 0 (the identity).
    """
    angle = safe_norm(theta, jnp.ones(theta.shape[:-1], bool), placeholder=0.0)
    half = 0.5 * angle
    # sin(half)/angle = 0.5 sinc(half/pi); jnp.sinc has a correct derivative at 0.
    scale = 0.5 * jnp.sinc(half / jnp.pi)
    return jnp.concatenate([jnp.cos(half)[..., None], scale[..., None] * theta], -1)


def matrix(orientation: Float[Array, "*#b q"], dim: int) -> Float[Array, "*#b d d"]:
    """Rotation matrix of an orientation (angle in 2-D, unit quaternion in 3-D)."""
    if dim == 2:
        a = orientation[..., 0]
        c, s = jnp.cos(a), jnp.sin(a)
        return jnp.stack([jnp.stack([c, -s], -1), jnp.stack([s, c], -1)], -2)
    w, x, y, z = (orientation[..., i] for i in range(4))
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return jnp.stack([jnp.stack(r, -1) for r in rows], -2)


def rotate(orientation: Float[Array, "*#b q"], increment: Float[Array, "*#b a"], dim):
    """Orientation after a further rotation by the rotation vector `increment`
    (applied in the world frame, i.e. R_new = R(increment) R_old)."""
    if dim == 2:
        return orientation + increment
    q = quaternion_multiply(quaternion_from_rotation_vector(increment), orientation)
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def cross(a: Float[Array, "*#b d"], b: Float[Array, "*#b d"]) -> Float[Array, "*#b a"]:
    """a x b: the z component (shape (..., 1)) in 2-D, the vector in 3-D."""
    if a.shape[-1] == 2:
        return (a[..., :1] * b[..., 1:2]) - (a[..., 1:2] * b[..., :1])
    return jnp.cross(a, b)


def spin_cross(omega: Float[Array, "*#b a"], r: Float[Array, "*#b d"]):
    """omega x r for an angular vector omega (one z component in 2-D)."""
    if r.shape[-1] == 2:
        return omega * jnp.concatenate([-r[..., 1:2], r[..., :1]], axis=-1)
    return jnp.cross(omega, r)


def inertia_of(offsets: Float[Array, "*n d"]) -> Float[Array, "*n a a"]:
    """Per-unit-mass inertia tensor of points at `offsets` from the axis point:
    |r|^2 in 2-D (1x1), |r|^2 I - r r^T in 3-D."""
    sq = jnp.sum(offsets**2, axis=-1)
    if offsets.shape[-1] == 2:
        return sq[..., None, None]
    eye = jnp.eye(3, dtype=offsets.dtype).reshape((1,) * sq.ndim + (3, 3))
    return sq[..., None, None] * eye - offsets[..., :, None] * offsets[..., None, :]
