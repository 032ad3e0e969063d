"""Numerical helpers with safe gradients (the "double where"). No physics here."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float


def safe_norm(
    x: Float[Array, "*batch d"], mask: Bool[Array, "*batch"], placeholder: float = 1.0
) -> Float[Array, "*batch"]:
    """Euclidean norm over the last axis, `placeholder` where `mask` is False.

    Uses the double-where trick so that neither the value nor the gradient is NaN for
    coincident points (r = 0) or padded pairs (jax-ml/jax#5798).
    """
    sq = last_axis_dot(x, x)
    ok = jnp.logical_and(mask, sq > 0)
    safe_sq = jnp.where(ok, sq, 1.0)
    return jnp.where(ok, jnp.sqrt(safe_sq), placeholder)


def take_rows(field: Array, index: Array) -> Array:
    """Gather `field[index]` along axis 0, with zeros for the sentinel index n."""
    return jnp.take(field, index, axis=0, mode="fill", fill_value=0)


def small_determinant(m: Float[Array, "*batch d d"]) -> Float[Array, "*batch"]:
    """Determinant of a batch of 1x1, 2x2 or 3x3 matrices, written out.

    XLA's CPU backend runs `jnp.linalg.det` as one LU factorisation per matrix,
    which for millions of 2x2 blocks costs more than the rest of the operator."""
    d = m.shape[-1]
    if d == 1:
        return m[..., 0, 0]
    if d == 2:
        return m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
    if d == 3:
        return jnp.sum(m[..., 0, :] * jnp.cross(m[..., 1, :], m[..., 2, :]), axis=-1)
    raise ValueError(f"small_determinant takes d <= 3, got d = {d}.")


def small_inverse(
    m: Float[Array, "*batch d d"], det: Float[Array, "*batch"]
) -> Float[Array, "*batch d d"]:
    """Inverse of a batch of 1x1, 2x2 or 3x3 matrices from the adjugate, given
    their determinants (`small_determinant`), which must be non-zero."""
    d = m.shape[-1]
    if d == 1:
        return 1.0 / m
    if d == 2:
        adjugate = jnp.stack(
            [
                jnp.stack([m[..., 1, 1], -m[..., 0, 1]], axis=-1),
                jnp.stack([-m[..., 1, 0], m[..., 0, 0]], axis=-1),
            ],
            axis=-2,
        )
    elif d == 3:
        # Rows of the adjugate are the cross products of the columns.
        c0, c1, c2 = m[..., :, 0], m[..., :, 1], m[..., :, 2]
        adjugate = jnp.stack(
            [jnp.cross(c1, c2), jnp.cross(c2, c0), jnp.cross(c0, c1)], axis=-2
        )
    else:
        raise ValueError(f"small_inverse takes d <= 3, got d = {d}.")
    return adjugate / det[..., None, None]


# XLA's CPU backend reduces a (n, k, d) array over k, or over a trailing d of 2 or 3,
# two to three times slower than it sums d separate (n, k) arrays over their last
# axis (benchmarks/NOTES.md §4), so the pair sums below are written per component.
# They also avoid a dot_general, which some GPUs would round to TF32 in float32.


# Choice: `jax.checkpoint` on the per-component sums: without it the backward pass
# stores each component slice of their (n, k, d) inputs next to the inputs
# themselves; with it the slices and products are recomputed. The forward program
# is unchanged; the residuals of a step fall 24.5 -> 20.7 MiB (2898 particles,
# float32) at the same gradient time (benchmarks/README.md, gradient_memory).
@jax.checkpoint
def last_axis_dot(a: Float[Array, "*batch d"], b: Float[Array, "*batch d"]):
    """sum_a a[..., a] b[..., a], one component at a time."""
    return sum(a[..., i] * b[..., i] for i in range(a.shape[-1]))


@jax.checkpoint
def pair_sum(
    coefficient: Float[Array, "n k"], vector: Float[Array, "n k d"]
) -> Float[Array, "n d"]:
    """sum_j coefficient_ij vector_ij, one component at a time."""
    d = vector.shape[-1]
    return jnp.stack(
        [jnp.sum(coefficient * vector[..., i], axis=1) for i in range(d)], axis=-1
    )
