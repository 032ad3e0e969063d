"""Host-side construction of the rigid bodies' sub-state (NumPy; validates)."""

import math

import jax.numpy as jnp
import numpy as np

from .._state import RigidState
from .._types import Kind
from . import rotation as rot


def body_indices(body, capacity: int, active: np.ndarray) -> tuple[np.ndarray, int]:
    """Body index of every slot (-1 for none) from `body` (one entry per initial
    particle or per slot), and the number of bodies; refuses indices that are not
    -1 or 0..b-1 with every body present, and bodies on inactive slots."""
    body = np.asarray(body)
    if (
        body.ndim != 1
        or body.shape[0] > capacity
        or not np.issubdtype(body.dtype, np.integer)
    ):
        raise ValueError(
            f"body must be a 1-D integer array of at most {capacity} entries, got "
            f"shape {body.shape} and dtype {body.dtype}."
        )
    ids = np.full(capacity, -1, np.int64)
    ids[: body.shape[0]] = body
    count = int(ids.max()) + 1 if ids.max() >= 0 else 0
    if count == 0:
        raise ValueError("body assigns no particle to a body (all entries are -1).")
    present = np.unique(ids[ids >= 0])
    if ids.min() < -1 or len(present) != count:
        raise ValueError(
            f"body indices must be -1 or 0..b-1 with every body present; got "
            f"{sorted(set(ids.tolist()) - {-1})}."
        )
    if np.any((ids >= 0) & ~np.asarray(active)):
        raise ValueError("body assigns inactive (pool) slots to a body.")
    return ids, count


def _finite(value, name: str, shape: tuple[int, ...], wanted: str) -> np.ndarray:
    """`value` broadcast to `shape` as a finite float array (ValueError naming
    `name` and what was `wanted` otherwise)."""
    try:
        out = np.broadcast_to(np.asarray(value, np.float64), shape).copy()
    except ValueError:
        raise ValueError(
            f"{name} must be {wanted}, got shape {np.shape(value)}."
        ) from None
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name} must be finite, got {out.tolist()}.")
    return out


def per_body(value, name: str, count: int) -> np.ndarray:
    """A scalar or one value per body, as a finite float array of shape (b,)."""
    return _finite(value, name, (count,), f"a scalar or one value per body ({count})")


def per_body_rows(value, name: str, count: int, size: int) -> np.ndarray | None:
    """None, or one row of `size` values for all bodies or per body, as a finite
    float array of shape (b, size)."""
    if value is None:
        return None
    wanted = f"{size} value(s) for all bodies or per body ({count})"
    return _finite(value, name, (count, size), wanted)


def orientations(orientation, count: int, dim: int) -> np.ndarray:
    """Orientations (an angle per body in 2-D, a unit quaternion per body in 3-D)
    from degrees (an angle, or a rotation vector in 3-D); zero if None."""
    if orientation is None:
        degrees = np.zeros((count, 3 if dim == 3 else 1))
    else:
        degrees = np.asarray(orientation, np.float64)
        degrees = (
            degrees.reshape(count, -1) if degrees.ndim else np.full((count, 1), degrees)
        )
        if degrees.shape != (count, 1 if dim == 2 else 3):
            what = "an angle" if dim == 2 else "a rotation vector"
            raise ValueError(
                f"orientation must give {what} (degrees) per body for {count} "
                f"bodies; got shape {degrees.shape}."
            )
    radians = np.deg2rad(degrees)
    if dim == 2:
        return radians
    return np.asarray(rot.quaternion_from_rotation_vector(jnp.asarray(radians)))


def _frame(arm: np.ndarray, velocity: np.ndarray, spacing: float, label: str):
    """A body's inertia (unit particle mass) and the rigid motion (V, omega) that
    keeps the momentum and angular momentum of its particles' velocities."""
    inertia = np.asarray(rot.inertia_of(jnp.asarray(arm))).sum(axis=0)
    size = inertia.shape[0] if inertia.ndim else 1
    if np.linalg.det(np.atleast_2d(inertia)) <= 1e-12 * (len(arm) * spacing**2) ** size:
        raise ValueError(f"{label} has a degenerate (collinear) particle set.")
    v = velocity.mean(axis=0)
    spin = np.asarray(rot.cross(jnp.asarray(arm), jnp.asarray(velocity))).sum(axis=0)
    w = np.linalg.solve(np.atleast_2d(inertia), np.atleast_1d(spin))
    return v, w


def _closest(a: np.ndarray, b: np.ndarray, cutoff: float) -> float:
    """Smallest distance between points of `a` and `b` if below `cutoff`, else inf
    (only points of `b` in the box of `a` widened by `cutoff` are compared)."""
    if len(a) == 0 or len(b) == 0:
        return math.inf
    near = np.all((b >= a.min(0) - cutoff) & (b <= a.max(0) + cutoff), axis=1)
    b = b[near]
    best = math.inf
    for start in range(0, len(b), 512):
        chunk = b[start : start + 512]
        d = np.linalg.norm(a[:, None, :] - chunk[None, :, :], axis=-1)
        best = min(best, float(d.min()))
    return best


def rigid_state(
    position: np.ndarray,
    velocity: np.ndarray,
    kind: np.ndarray,
    active: np.ndarray,
    ids: np.ndarray,
    count: int,
    orientation: np.ndarray,
    spacing: float,
    dtype,
) -> tuple[RigidState, np.ndarray, np.ndarray]:
    """The bodies' sub-state for the slots of `ids` (from `body_indices`), and the
    particles' kinds and velocities with every body particle `Kind.RIGID` and moving
    rigidly (the rigid motion with its particles' momentum and angular momentum).

    Raises:
        ValueError: for bodies of fewer than two particles or with a degenerate
            inertia, and bodies overlapping each other or other particles (closer
            than half a spacing).
    """
    n, dim = position.shape
    rotation = np.asarray(rot.matrix(jnp.asarray(orientation), dim))
    reference = np.zeros((n, dim))
    centre = np.zeros((count, dim))
    v_body = np.zeros((count, dim))
    w_body = np.zeros((count, rot.spin_size(dim)))
    velocity, kind = velocity.copy(), kind.copy()
    others = np.where(active & (ids < 0))[0]
    for b in range(count):
        members = np.where(ids == b)[0]
        if len(members) < 2:
            raise ValueError(f"Body {b} has {len(members)} particle(s); need >= 2.")
        centre[b] = position[members].mean(axis=0)
        arm = position[members] - centre[b]
        reference[members] = arm @ rotation[b]  # R^T arm, row-wise
        v_body[b], w_body[b] = _frame(arm, velocity[members], spacing, f"Body {b}")
        velocity[members] = v_body[b] + np.asarray(
            rot.spin_cross(jnp.asarray(w_body[b])[None], jnp.asarray(arm))
        )
        kind[members] = int(Kind.RIGID)
        rest = np.concatenate([others, np.where(ids > b)[0]])
        gap = _closest(position[members], position[rest], 0.5 * spacing)
        if gap < 0.5 * spacing:
            raise ValueError(
                f"Body {b} overlaps other particles (closest at {gap:.3g} m < 0.5 "
                "spacing): move it, or remove the wall or fluid particles it covers."
            )
    state = _at_rest(ids, reference, centre, orientation, v_body, w_body, dtype)
    return state, kind, velocity


def _at_rest(
    ids: np.ndarray,
    reference: np.ndarray,
    centre: np.ndarray,
    orientation: np.ndarray,
    velocity: np.ndarray,
    angular_velocity: np.ndarray,
    dtype,
) -> RigidState:
    """The sub-state of bodies in the given placement and motion, with no force,
    impulse or friction yet."""
    count, dim = centre.shape
    zeros_b = jnp.zeros((count, dim), dtype)
    zeros_a = jnp.zeros((count, rot.spin_size(dim)), dtype)
    return RigidState(
        body=jnp.asarray(ids, jnp.int32),
        reference=jnp.asarray(reference, dtype),
        centre=jnp.asarray(centre, dtype),
        orientation=jnp.asarray(
            orientation.reshape(count, rot.orientation_size(dim)), dtype
        ),
        velocity=jnp.asarray(velocity, dtype),
        angular_velocity=jnp.asarray(angular_velocity, dtype),
        force=zeros_b,
        torque=zeros_a,
        contact_force=zeros_b,
        impulse=zeros_b,
        angular_impulse=zeros_a,
        friction=zeros_b,
        sliding=jnp.zeros((count,), bool),
        wall_push=jnp.zeros(reference.shape, dtype),
    )
