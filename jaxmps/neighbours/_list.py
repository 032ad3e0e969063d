"""Sort-based cell-hash neighbour lists with static shapes and overflow flags.

Algorithm (all loop bounds static):
1. cell coordinates floor((x - origin) / cell_size), clamped into the grid; active
   particles outside the box are *flagged* (`outside`) but stay in the search, in the
   boundary cells, where the exact distance test still finds all their neighbours;
   inactive slots get the sentinel cell id `n_cells` so they sort last;
2. sort by cell id (`sort_by_cell`), and the start of each cell in the sorted order;
3. the stencil of a particle is the (2 reach + 1)^d cells around it (cells of edge
   radius / reach). Sorted by cell id, the cells of one stencil row along the last
   axis hold one contiguous range of particles, so the candidates of a particle are
   its rows' ranges laid end to end, up to `candidate_capacity` of them (more sets
   `cell_overflow`); candidates within `radius` are compacted, in candidate order,
   into `max_neighbours` slots, empty slots holding the sentinel index n.

Performance (measured on a 2-core CPU, 2-D dam break; benchmarks/NOTES.md):
distances are computed one coordinate at a time (gathering rows of an (n, d) array
with d = 2 or 3 as the minor axis was 7x slower); the compaction selects the k-th
hit from the hit bits packed into 32-bit words (population counts) instead of a
cumulative sum and a scatter (5x slower on CPU); and the row ranges test only the
particles actually in the stencil cells (about 3x the neighbour count with
reach 2), where fixed per-cell slots tested 9 x the fullest cell's capacity.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._numerics import finite_rows, last_axis_dot
from ._grid import Grid, stencil


class Neighbours(eqx.Module):
    """Fixed-capacity neighbour lists.

    Attributes:
        index: neighbours j of particle i (j != i), sentinel n in empty slots.
        count: true number of neighbours within the search radius (may exceed the
            slots); for lists carried by `reuse_or_build`, the listed entries.
        neighbour_overflow: some particle had more neighbours than slots.
        cell_overflow: the stencil cells of some particle held more particles
            than `Grid.candidate_capacity`.
        outside: active particles whose position lies outside the grid box.
        with_skin: the lists hold every pair within the search radius plus the
            skin, so that they can be carried (`NeighbourCache`); False where the
            pairs within the skin did not fit in the slots and only those within
            the radius were listed (`build`).
    """

    index: Int[Array, "n k"]
    count: Int[Array, " n"]
    neighbour_overflow: Bool[Array, ""]
    cell_overflow: Bool[Array, ""]
    outside: Bool[Array, " n"]
    with_skin: Bool[Array, ""]


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
    # Row tests one component at a time (XLA's CPU backend reduces a minor axis of
    # 2 or 3 element by element).
    finite = finite_rows(rel)
    rel = jnp.where(finite[:, None], rel, 0.0)
    coords = jnp.floor(rel).astype(jnp.int32)
    upper = jnp.asarray(grid.shape, dtype=jnp.int32)[None, :] - 1
    outside = ~finite
    for axis, cells in enumerate(grid.shape):
        c = coords[:, axis]
        outside = outside | (c < 0) | (c >= cells)
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
    rank = jnp.broadcast_to(jnp.arange(k, dtype=jnp.int32), (rows, k))  # s-th hit
    # The s-th hit's word: the first whose running total exceeds s; its rank
    # inside that word and the word itself, accumulated over the words before it
    # (no gathers).
    found = rank < through[:, -1:]
    word_of = jnp.zeros_like(rank)
    word = jnp.broadcast_to(words[:, :1], (rows, k))
    before = jnp.zeros_like(rank)  # hits in the words before word_of
    for w in range(1, words_per_row):
        later = through[:, w - 1 : w] <= rank
        word_of = word_of + later.astype(jnp.int32)
        word = jnp.where(later, words[:, w : w + 1], word)
        before = jnp.where(later, through[:, w - 1 : w], before)
    rank = rank - before
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


def sort_by_cell(
    cell_id: Int[Array, " n"],
) -> tuple[Int[Array, " n"], Int[Array, " n"]]:
    """The stable argsort of `cell_id` (non-negative int32) and the sorted ids.

    One sort of packed 64-bit keys (cell id << 32 | particle index): XLA sorts a
    single array of a primitive type with a vectorised routine, where an argsort
    carries a second operand through a generic comparator. Measured on CPU: 0.6 ms
    against 3.0 ms at 25k particles, 2.5 against 12 ms at 90k (benchmarks/NOTES.md
    §6). The keys are unique, so the order is the stable one. The 64-bit keys are
    built under a local `jax.enable_x64`, which changes only the dtypes traced
    inside it; the results are int32 again.
    """
    n = cell_id.shape[0]
    with jax.enable_x64(True):
        key = (cell_id.astype(jnp.uint64) << 32) | jnp.arange(n, dtype=jnp.uint64)
        key = jnp.sort(key)
        order = (key & 0xFFFFFFFF).astype(jnp.int32)
        sorted_id = (key >> 32).astype(jnp.int32)
    return order, sorted_id


def build(
    grid: Grid,
    position: Float[Array, "n d"],
    active: Bool[Array, " n"],
    max_neighbours: int,
    radius: float,
    skin: float = 0.0,
) -> Neighbours:
    """Neighbour lists of all active particles within `radius` + `skin` (strictly
    less), or, where those pairs do not fit in `max_neighbours` slots for some
    particle, within `radius` only (`Neighbours.with_skin` False: such lists
    cannot be carried). `neighbour_overflow` and `count` refer to `radius`.

    Requires `grid.radius >= radius + skin`. Differentiation: the lists are integer
    data; positions are `stop_gradient`-ed here and gradients flow through the pair
    geometry evaluated afterwards (`operators.make_pairs`).
    """
    reach = radius + skin
    if grid.radius < reach * (1 - 1e-12):
        raise ValueError(
            f"Grid.cell_size x Grid.reach = {grid.radius} is smaller than the search "
            f"radius {reach}."
        )
    n, dim = position.shape
    s, capacity = grid.reach, grid.candidate_capacity
    x = jax.lax.stop_gradient(position)
    coords, outside = cell_coordinates(grid, x)
    outside = jnp.logical_and(outside, active)
    n_cells = grid.n_cells
    cell_id = jnp.where(active, _flatten(coords, grid.shape), n_cells)
    order, sorted_id = sort_by_cell(cell_id)
    # start[c]: first sorted position of cell c or any later cell (a scatter-min and
    # a reverse running minimum: 4x faster on CPU than searchsorted over the cells).
    positions = jnp.arange(n, dtype=jnp.int32)
    start = jnp.full(n_cells + 1, n, jnp.int32).at[sorted_id].min(positions)
    start = jax.lax.cummin(start, reverse=True)
    rank = jnp.zeros(n, jnp.int32).at[order].set(positions)

    # The stencil as rows along the last axis: in sorted order each row's cells
    # (2s + 1 consecutive cell ids) hold one contiguous range of particles.
    lead = jnp.asarray(stencil(dim - 1, s)).reshape(-1, dim - 1)  # (R, d - 1)
    rows = lead.shape[0]
    lead_shape = jnp.asarray(grid.shape[:-1], dtype=jnp.int32)[None, None, :]
    row_lead = coords[:, None, :-1] + lead[None, :, :]  # (n, R, d - 1)
    in_grid = jnp.all((row_lead >= 0) & (row_lead < lead_shape), axis=-1)
    row_base = grid.shape[-1] * _flatten(
        jnp.clip(row_lead, 0, lead_shape - 1), grid.shape[:-1]
    )
    lo_cell = jnp.maximum(coords[:, -1] - s, 0)[:, None]
    hi_cell = jnp.minimum(coords[:, -1] + s, grid.shape[-1] - 1)[:, None]
    lo = start[row_base + lo_cell]
    length = jnp.where(in_grid, start[row_base + hi_cell + 1] - lo, 0)  # (n, R)
    through = jnp.cumsum(length, axis=1)  # candidates in rows 0..r
    cell_overflow = jnp.max(jnp.where(active, through[:, -1], 0)) > capacity

    # Candidate t of a particle is in the first row whose running total exceeds t.
    t = jnp.arange(capacity, dtype=jnp.int32)[None, :]
    # Its sorted position is t + shift[row]; shift[row] is accumulated over the
    # rows that end at or before t, one (n, c) comparison per row. (An (n, c, R)
    # comparison summed over R and a gather of shift by row cost more: XLA's CPU
    # backend reduces the short minor axis R element by element. The build took
    # 8.0 -> 4.9 ms at 25k particles in 2-D, 530 -> 451 ms at 137k in 3-D, with
    # the same lists; benchmarks/NOTES.md §7.)
    shift = lo - (through - length)  # (n, R)
    listed = t < through[:, -1:]
    offset = jnp.broadcast_to(shift[:, :1], (n, capacity))
    for r in range(1, rows):
        step = shift[:, r : r + 1] - shift[:, r - 1 : r]
        offset = offset + jnp.where(through[:, r - 1 : r] <= t, step, 0)
    slot = jnp.where(listed, t + offset, 0)

    dist2 = jnp.zeros(slot.shape, x.dtype)
    for axis in range(dim):
        component = x[:, axis]
        dist2 = dist2 + (component[order][slot] - component[:, None]) ** 2
    candidate = listed & (slot != rank[:, None]) & active[:, None]
    hit = candidate & (dist2 < radius**2)
    count = jnp.sum(hit, axis=1, dtype=jnp.int32)
    neighbour_overflow = jnp.max(count) > max_neighbours
    with_skin = jnp.asarray(skin > 0)
    if skin > 0:
        # The skin's pairs only where every particle's fit (a whole-list choice, so
        # that carried lists are complete or not carried).
        in_reach = candidate & (dist2 < reach**2)
        with_skin = (
            jnp.max(jnp.sum(in_reach, axis=1, dtype=jnp.int32)) <= max_neighbours
        )
        hit = jnp.where(with_skin, in_reach, hit)
    chosen = first_hits(hit, slot, max_neighbours, n)
    index = jnp.append(order, jnp.int32(n))[chosen]
    return Neighbours(
        index=index,
        count=count,
        neighbour_overflow=neighbour_overflow,
        cell_overflow=cell_overflow,
        outside=outside,
        with_skin=with_skin,
    )


class NeighbourCache(eqx.Module):
    """Neighbour lists carried from search to search (a Verlet list).

    Lists are built within r_e + skin. While no two particles that can have
    become neighbours have moved apart or together by the skin since the build
    (`lists_hold`), and no slot has been switched on or off, every pair closer
    than r_e lies in the carried lists, so a step uses them at its start (r^k) and
    at its predicted positions (r*) instead of searching (`carried_search`); the
    positions of the build are kept, so the moves add up over the steps until the
    next search.

    Attributes:
        index: the carried lists, sentinel n in empty slots.
        position: the positions they were built at (no gradient).
        active: the active mask they were built for.
        valid: False until a list has been stored, and for lists that could not
            hold the skin's pairs or overflowed.
    """

    index: Int[Array, "n k"]
    position: Float[Array, "n d"]
    active: Bool[Array, " n"]
    valid: Bool[Array, ""]

    @classmethod
    def empty(cls, position: Float[Array, "n d"], active: Bool[Array, " n"], k: int):
        """A cache that forces the first search."""
        n = position.shape[0]
        return cls(
            index=jnp.full((n, k), n, jnp.int32),
            position=jax.lax.stop_gradient(position),
            active=active,
            valid=jnp.asarray(False),
        )

    @classmethod
    def of(cls, nbrs: Neighbours, position, active) -> "NeighbourCache":
        """The lists `nbrs`, built at `position` for `active`, kept for later."""
        return cls(
            index=nbrs.index,
            position=jax.lax.stop_gradient(position),
            active=active,
            valid=nbrs.with_skin & ~(nbrs.neighbour_overflow | nbrs.cell_overflow),
        )


def lists_hold(
    grid: Grid,
    built_at: Float[Array, "n d"],
    moved: Float[Array, "n d"],
    active: Bool[Array, " n"],
    radius: float,
    skin: float,
) -> Bool[Array, ""]:
    """Whether lists built within `radius` + `skin` at `built_at` still hold every
    pair closer than `radius` after the moves `moved` (the relative-displacement
    criterion of a Verlet list).

    A pair (i, j) closer than `radius` now was closer than radius + |m_i - m_j|
    at the build, so it is listed if |m_i - m_j| < skin. The plain test, every
    move under skin / 2, bounds |m_i - m_j| by twice the largest move; where it
    fails (a fast front), the moves are compared within regions: cells of edge
    h = 2 `grid.radius` at the build's positions, each with the bounding box of
    the moves over its 3^d block of cells. While every move is under
    (h - radius) / 2, a pair that can have come within `radius` lies within one
    such block, and the box's diagonal bounds its relative move. Water sliding
    past a fixed wall may thus move by the whole skin before a search (twice as
    far as the plain test allows), water moving together further still.
    Non-finite moves fail both tests.
    """
    dim = built_at.shape[1]
    sq = jnp.where(active, last_axis_dot(moved, moved), 0.0)
    largest = jnp.max(sq)
    everywhere = 4 * largest < skin**2
    size = 2 * grid.radius
    factor = 2 * grid.reach
    shape = tuple(-(-cells // factor) for cells in grid.shape)
    n_cells = int(np.prod(shape))
    window, strides, pad = (3,) * dim, (1,) * dim, ((1, 1),) * dim

    def within_regions():
        origin = jnp.asarray(grid.origin, dtype=built_at.dtype)
        coords = jnp.floor((built_at - origin[None, :]) / size).astype(jnp.int32)
        coords = jnp.clip(coords, 0, jnp.asarray(shape, dtype=jnp.int32)[None, :] - 1)
        # Inactive particles get an id past the last region: segment ops drop it.
        cell = jnp.where(active, _flatten(coords, shape), n_cells)
        columns = [moved[:, axis] for axis in range(dim)]
        lo = [jax.ops.segment_min(m, cell, n_cells).reshape(shape) for m in columns]
        hi = [jax.ops.segment_max(m, cell, n_cells).reshape(shape) for m in columns]
        occupied = hi[0] >= lo[0]  # an empty region's min is +inf, its max -inf
        extent2 = jnp.zeros(shape, moved.dtype)
        for low, high in zip(lo, hi, strict=True):
            low = jax.lax.reduce_window(low, jnp.inf, jax.lax.min, window, strides, pad)
            high = jax.lax.reduce_window(
                high, -jnp.inf, jax.lax.max, window, strides, pad
            )
            extent2 = extent2 + jnp.where(occupied, high - low, 0.0) ** 2
        return (jnp.max(extent2) < skin**2) & (4 * largest < (size - radius) ** 2)

    return everywhere | jax.lax.cond(everywhere, lambda: True, within_regions)


def carried_search(
    grid: Grid,
    position: Float[Array, "n d"],
    active: Bool[Array, " n"],
    max_neighbours: int,
    radius: float,
    skin: float,
    cache: NeighbourCache,
    batch_axis: str | None = None,
) -> tuple[Neighbours, NeighbourCache]:
    """Neighbour lists within `radius` at `position`, and the cache to carry on:
    the cached lists (and the same cache) while they still hold every such pair
    (`lists_hold`), else a new search (`build` with `skin`) and a cache of its
    lists. The cached lists hold some pairs beyond `radius` too, which the pair
    geometry masks; their slot order differs from a new search's, so sums over
    neighbours agree to round-off, not bit for bit.

    The choice is a `lax.cond`. Under a plain `vmap` it becomes a select that runs
    the search as well, so batched runs keep the results but not the saving. With
    `batch_axis`, the name of the enclosing `vmap`'s axis (`jax.vmap(...,
    axis_name=...)`, as `jaxmps.sweep` runs), the members decide together: the
    carried lists are used when every member may use them, else every member
    searches, and the choice stays a branch.
    """
    x = jax.lax.stop_gradient(position)
    reusable = (
        cache.valid
        & jnp.all(active == cache.active)
        & lists_hold(grid, cache.position, x - cache.position, active, radius, skin)
    )
    if batch_axis is not None:
        # One decision for the whole batch.
        reusable = jax.lax.pmin(reusable.astype(jnp.int32), batch_axis) > 0

    def carried():
        _, outside = cell_coordinates(grid, x)
        nbrs = Neighbours(
            index=cache.index,
            count=jnp.sum(cache.index < x.shape[0], axis=1, dtype=jnp.int32),
            neighbour_overflow=jnp.asarray(False),
            cell_overflow=jnp.asarray(False),
            outside=jnp.logical_and(outside, active),
            with_skin=jnp.asarray(True),
        )
        return nbrs, cache

    def searched():
        nbrs = build(grid, x, active, max_neighbours, radius, skin)
        return nbrs, NeighbourCache.of(nbrs, x, active)

    return jax.lax.cond(reusable, carried, searched)


def reuse_or_build(
    grid: Grid,
    position: Float[Array, "n d"],
    active: Bool[Array, " n"],
    max_neighbours: int,
    radius: float,
    skin: float,
    cache: NeighbourCache,
    batch_axis: str | None = None,
) -> Neighbours:
    """The lists of `carried_search`, without the cache to carry on."""
    return carried_search(
        grid, position, active, max_neighbours, radius, skin, cache, batch_axis
    )[0]


def search(
    grid: Grid,
    position: Float[Array, "n d"],
    active: Bool[Array, " n"],
    max_neighbours: int,
    radius: float,
    skin: float,
    cache: NeighbourCache | None = None,
    batch_axis: str | None = None,
) -> tuple[Neighbours, NeighbourCache | None]:
    """The neighbour stage of a step: lists of every pair closer than `radius`,
    searched within radius + `skin` so that they can be carried, and the cache to
    carry on (None without a `cache`).

    With a `cache` (lists carried from an earlier search), those are used instead
    of a search while they still hold every such pair (`carried_search`, where
    `batch_axis` is explained). Pairs beyond `radius` are masked afterwards by the
    pair geometry (`operators.Pairs.valid`).
    """
    if cache is None:
        return build(grid, position, active, max_neighbours, radius, skin), None
    return carried_search(
        grid, position, active, max_neighbours, radius, skin, cache, batch_axis
    )
