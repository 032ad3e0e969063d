"""Numerical helpers with safe gradients (the "double where"). No physics here."""

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float


def safe_norm(
    x: Float[Array, "*batch d"], mask: Bool[Array, "*batch"], placeholder: float = 1.0
) -> Float[Array, "*batch"]:
    """Euclidean norm over the last axis, `placeholder` where `mask` is False.

    Uses the double-where trick so that neither the value nor the gradient is NaN for
    coincident points (r = 0) or padded pairs (jax-ml/jax#5798).
    """
    sq = jnp.sum(x * x, axis=-1)
    ok = jnp.logical_and(mask, sq > 0)
    safe_sq = jnp.where(ok, sq, 1.0)
    return jnp.where(ok, jnp.sqrt(safe_sq), placeholder)


def take_rows(field: Array, index: Array) -> Array:
    """Gather `field[index]` along axis 0, with zeros for the sentinel index n."""
    return jnp.take(field, index, axis=0, mode="fill", fill_value=0)
