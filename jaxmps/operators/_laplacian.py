"""MPS Laplacian model."""

import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import take_rows
from ._pairs import Pairs


def laplacian(
    pairs: Pairs,
    field: Float[Array, " n *c"],
    n0: float,
    lam: float,
    dim: int,
) -> Float[Array, " n *c"]:
    """<lap phi>_i = 2d / (lambda n0) sum_j (phi_j - phi_i) w_ij (seed 000 eq. 2.1-6).

    `lam` is lambda in absolute units [m^2]. `field` may be scalar (n,) or vector
    (n, d) per particle.
    """
    diff = take_rows(field, pairs.index) - field[:, None]
    w = pairs.weight.reshape(pairs.weight.shape + (1,) * (field.ndim - 1))
    return (2.0 * dim / (lam * n0)) * jnp.sum(diff * w, axis=1)
