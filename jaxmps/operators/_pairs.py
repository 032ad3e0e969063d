"""Pair geometry of a neighbour list at one set of positions."""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._numerics import pair_differences, safe_norm
from .._types import PairVectors
from ._weight import AbstractWeight


class Pairs(eqx.Module):
    """Neighbour pairs (i, j) of every particle i, evaluated at some positions.

    Attributes:
        index: neighbour j of particle i, or the sentinel n for an empty slot.
        valid: slot holds a real neighbour with 0 < r_ij < r_e.
        offset: r_j - r_i [m] (zero where not valid), a tuple of d (n, k) arrays,
            one per axis (`_numerics` says why).
        distance: |r_j - r_i| [m] (r_e where not valid, so divisions stay finite).
        weight: w(|r_ij|) (zero where not valid).
    """

    index: Int[Array, "n k"]
    valid: Bool[Array, "n k"]
    offset: PairVectors
    distance: Float[Array, "n k"]
    weight: Float[Array, "n k"]


def make_pairs(
    index: Int[Array, "n k"],
    position: Float[Array, "n d"],
    weight: AbstractWeight,
    r_e: float,
) -> Pairs:
    """Evaluate offsets, distances and weights of the listed pairs at `position`.

    Gradients flow through positions; the integer neighbour indices carry none.
    """
    n = position.shape[0]
    index = jax.lax.stop_gradient(index)
    listed = index < n
    offset = tuple(jnp.where(listed, o, 0.0) for o in pair_differences(position, index))
    r = safe_norm(offset, listed, placeholder=r_e)
    valid = jnp.logical_and(listed, r < r_e)
    # Coincident particles (r = 0) get r = r_e from safe_norm: they are not neighbours
    # of each other. # Choice: a zero-distance pair is dropped rather than producing an
    # infinite weight; the collision guard keeps particles from reaching r = 0.
    w = weight(r, valid, r_e)
    return Pairs(index=index, valid=valid, offset=offset, distance=r, weight=w)
