"""Pressure-gradient correction of velocity and position (seed 000 eq. 2.2-8/9/10)."""

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._numerics import take_rows
from .._types import PRESSURE_KINDS, is_kind
from ..operators import AbstractGradient, Pairs


def pressure_gradient(
    gradient: AbstractGradient,
    pairs: Pairs,
    pressure: Float[Array, " n"],
    kind,
    active: Bool[Array, " n"],
    n0: float,
    dim: int,
    select: Bool[Array, "n k"] | None = None,
) -> Float[Array, "n d"]:
    """<grad P>_i over pressure-carrying neighbours.

    # Choice: dummy neighbours are left out of the gradient (and of the corrected
    # gradient's moment matrix), the gradient counterpart of their Neumann treatment
    # in the PPE (p_dummy = p_i contributes nothing).
    """
    carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    include = take_rows(carries, pairs.index)
    return gradient(pairs, pressure, n0, dim, include, select)
