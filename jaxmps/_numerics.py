"""Numerical helpers with safe gradients (the "double where"). No physics here."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int, Num

from ._types import PairVectors

# Layout of pair vectors. XLA's CPU backend handles an (n, k, d) array with d = 2 or
# 3 as its minor axis poorly: gathering its rows, reducing it over k, or taking a
# dot product over the trailing d runs two to five times slower than the same work
# on d separate (n, k) arrays (benchmarks/NOTES.md §1, §4 and §6; worst in float64).
# Pair vectors (offsets r_j - r_i, differences of vector fields) are therefore held
# as a tuple of d (n, k) arrays, one per axis (`_types.PairVectors`), and every sum
# below runs over one contiguous (n, k) array per component. A tuple rather than a
# stacked (d, n, k) array, so that no stacked copy has to be written: XLA fuses each
# component into its consumers. Per-component sums also avoid a dot_general, which
# some GPUs round to TF32 in float32.

# Choice: every dot product of the solver asks for full precision. JAX lets a GPU
# compute a float32 dot in TF32 (a 10-bit mantissa) by default: the CG's inner
# products would stall above its tolerance, and a 40 m hull's lever arms rotated by
# a TF32 product would sit centimetres off the body.
HIGHEST = jax.lax.Precision.HIGHEST


def einsum(subscripts: str, *operands: Array) -> Array:
    """`jnp.einsum` at full precision (`HIGHEST`)."""
    return jnp.einsum(subscripts, *operands, precision=HIGHEST)


def matmul(a: Array, b: Array) -> Array:
    """`a @ b` at full precision (`HIGHEST`)."""
    return jnp.matmul(a, b, precision=HIGHEST)


def vdot(a: Array, b: Array) -> Array:
    """`jnp.vdot` at full precision (`HIGHEST`)."""
    return jnp.vdot(a, b, precision=HIGHEST)


def safe_norm(
    x: Float[Array, "*batch d"] | PairVectors,
    mask: Bool[Array, "*batch"],
    placeholder: float = 1.0,
) -> Float[Array, "*batch"]:
    """Euclidean norm over the last axis of an array, or of a `PairVectors`;
    `placeholder` where `mask` is False.

    Uses the double-where trick so that neither the value nor the gradient is NaN for
    coincident points (r = 0) or padded pairs (jax-ml/jax#5798).
    """
    sq = component_dot(x, x) if isinstance(x, tuple) else last_axis_dot(x, x)
    ok = jnp.logical_and(mask, sq > 0)
    safe_sq = jnp.where(ok, sq, 1.0)
    return jnp.where(ok, jnp.sqrt(safe_sq), placeholder)


def is_concrete(*values) -> bool:
    """Whether every value is concrete (not a tracer of `jit`, `vmap` or `grad`), so
    that it can be checked on the host at trace time."""
    return not any(isinstance(v, jax.core.Tracer) for v in values)


def materialised(field: Array) -> Array:
    """`field`, written once to memory before the gathers that read it.

    XLA's CPU backend fuses a cheap producer (a cell index from positions, a
    smoothing sweep) into the gather that reads it, and then recomputes the
    producer for every gathered element: a cell index read by every pair slot ran
    10x slower that way, a multigrid level's correction read by each finer cell
    several times (benchmarks/NOTES.md §23). A scatter is never fused into its
    consumer, so the field is copied through one (the identity; its gradient is
    the cotangent)."""
    rows = jnp.arange(field.shape[0])
    return (
        jnp.zeros_like(field)
        .at[rows]
        .set(field, unique_indices=True, indices_are_sorted=True)
    )


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


def pair_differences(
    field: Num[Array, "n d"], index: Int[Array, "n k"]
) -> tuple[Num[Array, "n k"], ...]:
    """field_j - field_i of every listed pair, one (n, k) array per component (float
    fields give `PairVectors`); the sentinel index n reads field_j = 0 (callers mask
    empty slots by their weights)."""
    return tuple(
        take_rows(field[:, a], index) - field[:, a, None]
        for a in range(field.shape[-1])
    )


# Choice: `jax.checkpoint` on the per-component sums: without it the backward pass
# stores each component slice of their inputs next to the inputs themselves; with it
# the slices and products are recomputed. The forward program is unchanged; the
# residuals of a step fell 24.5 -> 20.7 MiB (2898 particles, float32) at the same
# gradient time (benchmarks/README.md, gradient_memory).
@jax.checkpoint
def component_dot(a: PairVectors, b: PairVectors) -> Float[Array, "n k"]:
    """sum_c a[c] b[c] of two pair vectors."""
    return sum(a_c * b_c for a_c, b_c in zip(a, b, strict=True))


@jax.checkpoint
def last_axis_dot(a: Float[Array, "*batch d"], b: Float[Array, "*batch d"]):
    """sum_c a[..., c] b[..., c], one component at a time (small per-particle or
    per-body vectors; pair vectors use `component_dot`)."""
    return sum(a[..., c] * b[..., c] for c in range(a.shape[-1]))


def finite_rows(*fields: Array) -> Array:
    """Whether every entry of each row of the (n,) or (n, d) `fields` is finite,
    one component at a time (XLA's CPU backend reduces a minor axis of 2 or 3
    element by element)."""
    finite = None
    for field in fields:
        width = 1 if field.ndim == 1 else field.shape[1]
        for c in range(width):
            column = field if field.ndim == 1 else field[:, c]
            ok = jnp.isfinite(column)
            finite = ok if finite is None else finite & ok
    return finite


@jax.checkpoint
def pair_sum(
    coefficient: Float[Array, "n k"], vector: PairVectors
) -> Float[Array, "n d"]:
    """sum_j coefficient_ij vector_ij, one component at a time."""
    return jnp.stack([jnp.sum(coefficient * v, axis=1) for v in vector], axis=-1)
