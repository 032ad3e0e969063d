"""Sort-based cell-hash neighbour lists with static shapes and overflow flags.

Algorithm (all loop bounds static):
1. cell coordinates floor((x - origin) / cell_size), clamped into the grid; active
   particles outside the box are *flagged* (`outside`) but stay in the search, in the
   boundary cells, where the exact distance test still finds all their neighbours;
   inactive slots get the sentinel cell id `n_cells` so they sort last;
2. argsort by cell id, and cell start offsets by `searchsorted` on the sorted ids;
3. for each particle, the 3^d stencil cells each contribute up to `cell_capacity`
   candidates; candidates within `radius` are compacted, in candidate order, into
   `max_neighbours` slots, empty slots holding the sentinel index n.

Performance (measured on a 2-core CPU, 4418 particles in 2-D, 126 candidates each;
benchmarks/NOTES.md): distances are computed one coordinate at a time (gathering
rows of an (n, d) array with d = 2 or 3 as the minor axis was 7x slower), and the
compaction selects the k-th hit from the hit bits packed into 32-bit words
(population counts) instead of a cumulative sum and a scatter (5x slower on CPU).
"""

import itertools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ._grid import Grid


class Neighbours(eqx.Module):
    """Fixed-capacity neighbour lists.

    Attributes:
        index: neighbours j of particle i (j != i), sentinel n in empty slots.
        count: true number of neighbours within the radius (may exceed the slots).
        neighbour_overflow: some particle had more neighbours than slots.
        cell_overflow: some cell held more particles than `cell_capacity`.
        outside: active particles whose position lies outside the grid box.
    """

    index: Int[Array, "n k"]
    count: Int[Array, " n"]
    neighbour_overflow: Bool[Array, ""]
    cell_overflow: Bool[Array, ""]
    outside: Bool[Array, " n"]


def _stencil(dim: int) -> np.ndarray:
    return np.array(list(itertools.product((-1, 0, 1), repeat=dim)), dtype=np.int32)


def _flatten(coords: Int[Array, "... d"], shape: tuple[int, ...]) -> Int[Array, "..."]:
    strides = np.cumprod((1,) + shape[:0:-1])[::-1].astype(np.int32)
    strides = jnp.asarray(strides).reshape((1,) * (coords.ndim - 1) + (-1,))
    return jnp.sum(coords * strides, axis=-1)


def cell_coordinates(
    grid: Grid, position: Float[Array, "n d"]
) -> tuple[Int[Array, "n d"], Bool[Array, " n"]]:
    """Clamped integer cell coordinates, and whether each point was outside the box."""
    origin = jnp.asarray(grid.origin, dtype=position.dtype)[None, :]
    rel = (position - origin) / grid.cell_size
    # Non-finite positions are mapped to cell 0 and reported as outside.
    finite = jnp.all(jnp.isfinite(rel), axis=-1)
    rel = jnp.where(finite[:, None], rel, 0.0)
    coords = jnp.floor(rel).astype(jnp.int32)
    upper = jnp.asarray(grid.shape, dtype=jnp.int32)[None, :] - 1
    outside = jnp.any((coords < 0) | (coords > upper), axis=-1) | ~finite
    return jnp.clip(coords, 0, upper), outside


def first_hits(
    hit: Bool[Array, "n c"], candidate: Int[Array, "n c"], k: int, sentinel: int
) -> Int[Array, "n k"]:
    """The candidates of the first k hits of each row, in order; `sentinel` where a
    row has fewer. Scatter-free: the hits are packed into 32-bit words and the s-th
    hit is found by population counts (a word, then a binary search in it)."""
    rows, c = hit.shape
    words_per_row = -(-c // 32)
    bits = jnp.pad(hit, ((0, 0), (0, 32 * words_per_row - c))).astype(jnp.uint32)
    shifts = jnp.arange(32, dtype=jnp.uint32)[None, None, :]
    bits = bits.reshape(rows, words_per_row, 32) << shifts
    words = jnp.sum(bits, axis=-1, dtype=jnp.uint32)  # disjoint bits: sum == or
    ones = jax.lax.population_count(words).astype(jnp.int32)
    through = jnp.cumsum(ones, axis=1)  # hits in words 0..w
    rank = jnp.arange(k, dtype=jnp.int32)[None, :]  # the s-th hit, s = 0..k-1
    word_of = jnp.sum(through[:, None, :] <= rank[..., None], axis=-1, dtype=jnp.int32)
    found = word_of < words_per_row
    word_of = jnp.minimum(word_of, words_per_row - 1)
    rank = rank - jnp.take_along_axis(through - ones, word_of, axis=1)
    word = jnp.take_along_axis(words, word_of, axis=1)
    # Largest bit position p with popcount(word & (2^p - 1)) <= rank.
    position = jnp.zeros_like(rank)
    for step in (16, 8, 4, 2, 1):
        trial = position + step
        below = jnp.where(
            trial >= 32,
            jnp.uint32(0xFFFFFFFF),
            (jnp.uint32(1) << jnp.minimum(trial, 31).astype(jnp.uint32)) - 1,
        )
        count = jax.lax.population_count(word & below).astype(jnp.int32)
        position = jnp.where(count <= rank, trial, position)
    column = jnp.minimum(32 * word_of + position, c - 1)
    return jnp.where(found, jnp.take_along_axis(candidate, column, axis=1), sentinel)


def build(
    grid: Grid,
    position: Float[Array, "n d"],
    active: Bool[Array, " n"],
    max_neighbours: int,
    radius: float,
) -> Neighbours:
    """Neighbour lists of all active particles within `radius` (strictly less).

    Requires `grid.cell_size >= radius`. Differentiation: the lists are integer
    data; positions are `stop_gradient`-ed here and gradients flow through the pair
    geometry evaluated afterwards (`operators.make_pairs`).
    """
    if grid.cell_size < radius:
        raise ValueError(
            f"Grid.cell_size={grid.cell_size} is smaller than the search radius "
            f"{radius}."
        )
    n, dim = position.shape
    x = jax.lax.stop_gradient(position)
    coords, outside = cell_coordinates(grid, x)
    outside = jnp.logical_and(outside, active)
    n_cells = grid.n_cells
    cell_id = jnp.where(active, _flatten(coords, grid.shape), n_cells)
    order = jnp.argsort(cell_id, stable=True)
    sorted_id = cell_id[order]
    start = jnp.searchsorted(sorted_id, jnp.arange(n_cells + 1), side="left")
    occupancy = start[1:] - start[:-1]
    cell_overflow = jnp.max(occupancy) > grid.cell_capacity

    stencil = jnp.asarray(_stencil(dim))
    shape = jnp.asarray(grid.shape, dtype=jnp.int32)[None, None, :]
    near = coords[:, None, :] + stencil[None, :, :]  # (n, 3^d, d)
    in_grid = jnp.all((near >= 0) & (near < shape), axis=-1)
    near_id = _flatten(jnp.clip(near, 0, shape - 1), grid.shape)
    first = start[near_id]
    filled = jnp.where(in_grid, jnp.minimum(occupancy[near_id], grid.cell_capacity), 0)
    slot = jnp.arange(grid.cell_capacity, dtype=jnp.int32)[None, None, :]
    pos = first[..., None] + slot  # (n, 3^d, C)
    candidate = jnp.where(
        slot < filled[..., None], order[jnp.clip(pos, 0, n - 1)], n
    ).reshape(n, -1)

    safe = jnp.minimum(candidate, n - 1)
    dist2 = jnp.zeros(candidate.shape, x.dtype)
    for axis in range(dim):
        component = x[:, axis]
        dist2 = dist2 + (component[safe] - component[:, None]) ** 2
    me = jnp.arange(n)[:, None]
    hit = (candidate < n) & (candidate != me) & (dist2 < radius**2) & active[:, None]
    count = jnp.sum(hit, axis=1, dtype=jnp.int32)
    neighbour_overflow = jnp.max(count) > max_neighbours
    index = first_hits(hit, candidate.astype(jnp.int32), max_neighbours, n)
    return Neighbours(
        index=index,
        count=count,
        neighbour_overflow=neighbour_overflow,
        cell_overflow=cell_overflow,
        outside=outside,
    )
