"""Free-surface detection (seed 000 §2.4.1)."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._numerics import take_rows
from .._types import PRESSURE_KINDS, Kinds, is_kind
from ..operators import Pairs


class FreeSurface(eqx.Module):
    """The beta rule n* < beta n0 (eq. 2.4-1) plus the isolated-surface filter of
    Masuda et al. (OMAE 2012): a flagged particle with at most `max_surface_neighbours`
    flagged neighbours and at least `min_neighbours` neighbours is un-flagged.

    beta itself is a Params field. Defaults N = 2, lim = 10 are the seed's Table 3.1-1.
    """

    max_surface_neighbours: int = 2
    min_neighbours: int = 10


def detect_surface(
    model: FreeSurface,
    beta: Float[Array, ""],
    n0: float,
    number_density: Float[Array, " n"],
    kind: Kinds,
    active: Bool[Array, " n"],
    pairs: Pairs,
    counts_as: Float[Array, " n"] | None = None,
) -> Bool[Array, " n"]:
    """Surface flags of pressure-carrying particles (fluid, walls, bodies).

    `counts_as`: per particle, how many lattice neighbours each of its
    neighbours stands for in the isolated-surface filter's count (None: 1). In
    a porous region the water stands sparser, and its pore weight
    (`Coupling.pores`) tracks the share of neighbours it lacks (at porosity 0.8
    in 2-D 1.36, against 1.40 measured: 13.9 neighbours in open water, 9.9 in
    the region); counted one by one, an interior particle there could have fewer than
    `min_neighbours` (7 at least), so a dip of its number density below beta n0
    stayed flagged: it took P = 0 and the pressure around it fell for a step.

    Discrete decision: carries no gradient with respect to beta or positions.
    """
    candidate = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    flagged = jnp.logical_and(candidate, number_density < beta * n0)
    flagged_nbrs = jnp.sum(pairs.valid & take_rows(flagged, pairs.index), axis=1)
    all_nbrs = jnp.sum(pairs.valid, axis=1)
    if counts_as is not None:
        all_nbrs = all_nbrs * counts_as
    isolated = (flagged_nbrs <= model.max_surface_neighbours) & (
        all_nbrs >= model.min_neighbours
    )
    return jnp.logical_and(flagged, ~isolated)
