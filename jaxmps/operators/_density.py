"""Particle number density."""

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._pairs import Pairs


def number_density(pairs: Pairs) -> Float[Array, " n"]:
    """n_i = sum_{j != i} w(|r_ij|) (seed 000 eq. 2.1-4)."""
    return jnp.sum(pairs.weight, axis=1)
