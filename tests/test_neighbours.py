"""Neighbour lists: equal to brute force in any particle order, overflow and
out-of-domain flags, the sort, and the lists carried between steps (when they are
reused, when searched again, and the joint decision of a batch)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import brute_force_neighbours, listed

import jaxmps
from jaxmps.neighbours import (
    Grid,
    NeighbourCache,
    build,
    candidate_counts,
    carried_search,
    lists_hold,
    reuse_or_build,
)


@pytest.mark.parametrize("reach", [1, 2])
@pytest.mark.parametrize("dim", [2, 3])
def test_matches_brute_force_random_order_with_inactive(rng, dim, reach):
    n = 400 if dim == 2 else 600
    x = rng.uniform(0.0, 1.0, (n, dim))
    active = rng.uniform(size=n) > 0.2
    radius = 0.15 if dim == 2 else 0.25
    grid = Grid(
        origin=(0.0,) * dim,
        cell_size=radius / reach,
        shape=(7 * reach,) * dim,
        candidate_capacity=200 if dim == 2 else 450,
        reach=reach,
    )
    nbrs = jax.jit(build, static_argnums=(0, 3, 4))(
        grid, jnp.asarray(x), jnp.asarray(active), 120, radius
    )
    assert not bool(nbrs.neighbour_overflow) and not bool(nbrs.cell_overflow)
    ref = brute_force_neighbours(x, active, radius)
    np.testing.assert_array_equal(listed(nbrs.index, n), ref)
    np.testing.assert_array_equal(np.asarray(nbrs.count), ref.sum(1))


def test_permutation_invariance(rng):
    x = rng.uniform(0.0, 1.0, (300, 2))
    active = np.ones(300, bool)
    grid = Grid(origin=(0.0, 0.0), cell_size=0.1, shape=(10, 10), candidate_capacity=80)
    perm = rng.permutation(300)
    a = build(grid, jnp.asarray(x), jnp.asarray(active), 40, 0.1)
    b = build(grid, jnp.asarray(x[perm]), jnp.asarray(active), 40, 0.1)
    assert not bool(a.cell_overflow) and not bool(a.neighbour_overflow)
    inv = np.argsort(perm)
    la = listed(a.index, 300)
    lb = listed(b.index, 300)[inv][:, inv]
    np.testing.assert_array_equal(la, lb)


def test_deliberate_overflows():
    # A clump of 12 nearly coincident particles: 11 neighbours each.
    x = np.concatenate([np.full((12, 2), 0.55), np.full((3, 2), 0.25)])
    x = x + np.linspace(0, 1e-3, 15)[:, None]
    x, active = jnp.asarray(x), jnp.ones(15, bool)

    def grid(capacity):
        return Grid(
            origin=(0.0, 0.0),
            cell_size=0.1,
            shape=(10, 10),
            candidate_capacity=capacity,
        )

    too_few_slots = build(grid(12), x, active, 5, 0.1)
    assert bool(too_few_slots.neighbour_overflow)
    assert not bool(too_few_slots.cell_overflow)
    assert int(too_few_slots.count.max()) == 11
    too_small_cells = build(grid(4), x, active, 11, 0.1)
    assert bool(too_small_cells.cell_overflow)
    enough = build(grid(12), x, active, 11, 0.1)
    assert not bool(enough.neighbour_overflow) and not bool(enough.cell_overflow)


def test_particles_outside_domain_flagged_not_dropped(rng):
    x = rng.uniform(0.0, 1.0, (200, 2))
    x[:5] = [[-0.05, 0.5], [-0.08, 0.52], [1.3, 0.2], [1.32, 0.21], [0.5, -0.4]]
    grid = Grid(origin=(0.0, 0.0), cell_size=0.1, shape=(10, 10), candidate_capacity=80)
    active = np.ones(200, bool)
    nbrs = build(grid, jnp.asarray(x), jnp.asarray(active), 60, 0.1)
    assert not bool(nbrs.cell_overflow)
    out = np.asarray(nbrs.outside)
    assert out[:5].all() and not out[5:].any()
    # Escaped particles still find each other and the particles near the boundary.
    np.testing.assert_array_equal(
        listed(nbrs.index, 200), brute_force_neighbours(x, active, 0.1)
    )


def test_nonfinite_positions_are_flagged():
    x = np.array([[0.5, 0.5], [np.nan, 0.5], [0.52, 0.5]])
    grid = Grid(origin=(0.0, 0.0), cell_size=0.1, shape=(10, 10), candidate_capacity=4)
    nbrs = build(grid, jnp.asarray(x), jnp.ones(3, bool), 4, 0.1)
    assert bool(nbrs.outside[1])


@pytest.mark.parametrize("dim", [2, 3])
def test_candidate_capacity_is_exact(rng, dim):
    """`candidate_counts` (host, sizes the capacity) counts what `build` tests: the
    fullest stencil fits exactly, one slot fewer overflows."""
    x = rng.uniform(0.0, 1.0, (300, dim))
    radius = 0.2

    def grid(capacity):
        return Grid(
            origin=(0.0,) * dim,
            cell_size=radius / 2,
            shape=(10,) * dim,
            candidate_capacity=capacity,
            reach=2,
        )

    most = int(candidate_counts(grid(1), x).max())
    fits = build(grid(most), jnp.asarray(x), jnp.ones(300, bool), 300, radius)
    assert not bool(fits.cell_overflow)
    np.testing.assert_array_equal(
        listed(fits.index, 300), brute_force_neighbours(x, np.ones(300, bool), radius)
    )
    short = build(grid(most - 1), jnp.asarray(x), jnp.ones(300, bool), 300, radius)
    assert bool(short.cell_overflow)


@pytest.mark.parametrize("x64", [False, True])
def test_sort_by_cell_is_the_stable_argsort_in_both_precisions(rng, x64):
    """The packed 64-bit keys give numpy's stable argsort, also inside a float32
    (x64 disabled) program, where the keys are built under a local enable_x64."""
    from jaxmps.neighbours._list import sort_by_cell

    # Many ties and large ids: 3000 particles in up to 2^20 cells.
    cells = rng.integers(0, 2**20, size=3000)
    cells[rng.random(3000) < 0.7] = rng.integers(0, 50, size=1)[0]
    with jax.enable_x64(x64):
        order, sorted_id = jax.jit(sort_by_cell)(jnp.asarray(cells, jnp.int32))
        assert order.dtype == jnp.int32 and sorted_id.dtype == jnp.int32
    np.testing.assert_array_equal(order, np.argsort(cells, kind="stable"))
    np.testing.assert_array_equal(sorted_id, np.sort(cells))


def _within(index, x, radius):
    """Pairs of the lists `index` closer than `radius` at positions x (bool n x n)."""
    n = x.shape[0]
    out = listed(index, n)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    return out & (d < radius)


def _unit_box_case(dim):
    """(particles, radius, skin, grid of cells (radius + skin) / 2) over the unit
    box, for random particles there."""
    n, radius, skin = (300, 0.15, 0.03) if dim == 2 else (400, 0.25, 0.05)
    grid = Grid(
        origin=(0.0,) * dim,
        cell_size=(radius + skin) / 2,
        shape=(12,) * dim if dim == 2 else (7,) * dim,
        candidate_capacity=300 if dim == 2 else 600,
        reach=2,
    )
    return n, radius, skin, grid


@pytest.mark.parametrize("dim", [2, 3])
def test_carried_lists_hold_every_pair_while_moves_stay_below_half_the_skin(rng, dim):
    n, radius, skin, grid = _unit_box_case(dim)
    x0 = rng.uniform(0.0, 1.0, (n, dim))
    active = rng.uniform(size=n) > 0.1
    first = build(grid, jnp.asarray(x0), jnp.asarray(active), 150, radius, skin)
    cache = NeighbourCache.of(first, jnp.asarray(x0), jnp.asarray(active))
    # Every active particle moves by just under skin / 2 in a random direction.
    step = rng.normal(size=(n, dim))
    step *= 0.499 * skin / np.linalg.norm(step, axis=1, keepdims=True)
    x1 = np.clip(x0 + step, 0.0, 0.999)
    reused = reuse_or_build(
        grid, jnp.asarray(x1), jnp.asarray(active), 150, radius, skin, cache
    )
    # The carried lists themselves, not a new search ...
    np.testing.assert_array_equal(np.asarray(reused.index), np.asarray(first.index))
    assert not bool(reused.neighbour_overflow) and not bool(reused.cell_overflow)
    # ... and they hold exactly the pairs a brute-force search finds now.
    ref = brute_force_neighbours(x1, active, radius)
    np.testing.assert_array_equal(_within(reused.index, x1, radius), ref)


# Cells of (radius + skin) / 2 for radius 0.15 and skin 0.03 over the unit square.
_SKIN_GRID = Grid(
    origin=(0.0, 0.0), cell_size=0.09, shape=(12, 12), candidate_capacity=300, reach=2
)


def test_lists_are_searched_again_after_a_long_move_or_a_new_particle(rng):
    n, radius, skin = 300, 0.15, 0.03
    x0 = rng.uniform(0.1, 0.9, (n, 2))
    active = np.ones(n, bool)
    active[-5:] = False
    grid = _SKIN_GRID
    first = build(grid, jnp.asarray(x0), jnp.asarray(active), 150, radius, skin)
    cache = NeighbourCache.of(first, jnp.asarray(x0), jnp.asarray(active))

    def check(x, active):
        got = reuse_or_build(
            grid, jnp.asarray(x), jnp.asarray(active), 150, radius, skin, cache
        )
        new = build(grid, jnp.asarray(x), jnp.asarray(active), 150, radius, skin)
        np.testing.assert_array_equal(np.asarray(got.index), np.asarray(new.index))
        ref = brute_force_neighbours(x, active, radius)
        np.testing.assert_array_equal(_within(got.index, x, radius), ref)

    # One particle moves by 1.1 skin (to where it gains neighbours), the rest stay.
    x1 = x0.copy()
    x1[0] += [1.1 * skin, 0.0]
    check(x1, active)
    # Nobody moves, but a pool slot is switched on next to particle 0.
    x2 = x0.copy()
    x2[-1] = x0[0] + [0.5 * radius, 0.0]
    switched = active.copy()
    switched[-1] = True
    check(x2, switched)
    # An empty cache (the first step of a rollout) searches.
    empty = NeighbourCache.empty(jnp.asarray(x0), jnp.asarray(active), 150)
    got = reuse_or_build(
        grid, jnp.asarray(x0), jnp.asarray(active), 150, radius, skin, empty
    )
    np.testing.assert_array_equal(np.asarray(got.index), np.asarray(first.index))


def test_neighbour_skin_settings_are_checked():
    import dataclasses

    import jaxmps

    x = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), -1).reshape(-1, 2)
    domain = ((-3.0, -3.0), (8.0, 8.0))
    with pytest.raises(ValueError, match="neighbour_skin"):
        jaxmps.make_scene(x, 1.0, domain, neighbour_skin=-0.1)
    scene = jaxmps.make_scene(x, 1.0, domain)
    assert scene.neighbour_skin == pytest.approx(0.3)
    assert scene.grid.radius >= scene.r_e + scene.neighbour_skin
    # A skin the grid's cells were not sized for is refused.
    with pytest.raises(ValueError, match="r_e \\+ neighbour_skin"):
        dataclasses.replace(scene, neighbour_skin=0.5)


def test_a_batch_decides_jointly_and_keeps_the_branch(rng):
    n, radius, skin = 200, 0.15, 0.03
    x0 = rng.uniform(0.1, 0.9, (n, 2))
    active = jnp.ones(n, bool)
    grid = _SKIN_GRID
    first = build(grid, jnp.asarray(x0), active, 150, radius, skin)
    cache = NeighbourCache.of(first, jnp.asarray(x0), active)
    # Member 0 stays put, member 1 moves one particle by more than the skin.
    x1 = x0.copy()
    x1[3] += [1.1 * skin, 0.0]
    xs = jnp.asarray(np.stack([x0, x1]))
    caches = jax.tree.map(lambda a: jnp.stack([a, a]), cache)

    def lists(x, c, batch_axis=None):
        return reuse_or_build(grid, x, active, 150, radius, skin, c, batch_axis).index

    plain = jax.vmap(lists)
    joint = jax.vmap(lambda x, c: lists(x, c, "batch"), axis_name="batch")
    joint_jaxpr = str(jax.make_jaxpr(joint)(xs, caches))
    got = joint(xs, caches)
    # A plain vmap turns the branch into a select; the joint decision keeps it.
    assert "cond[" not in str(jax.make_jaxpr(plain)(xs, caches))
    assert "cond[" in joint_jaxpr
    # Member 1 must search, so both do: same lists as a search, and the pairs.
    for x, index in zip(np.asarray(xs), np.asarray(got), strict=True):
        searched = build(grid, jnp.asarray(x), active, 150, radius, skin)
        np.testing.assert_array_equal(index, np.asarray(searched.index))
        ref = brute_force_neighbours(x, np.ones(n, bool), radius)
        np.testing.assert_array_equal(_within(index, x, radius), ref)
    # When every member may reuse, all use the carried lists.
    both = jnp.asarray(np.stack([x0, x0]))
    kept = joint(both, caches)
    np.testing.assert_array_equal(np.asarray(kept[1]), np.asarray(first.index))


def test_lists_without_room_for_the_skin_hold_the_radius_pairs_uncarried(rng):
    n, radius, skin = 300, 0.15, 0.03
    x = rng.uniform(0.1, 0.9, (n, 2))
    active = jnp.ones(n, bool)
    core = brute_force_neighbours(x, np.ones(n, bool), radius).sum(1).max()
    reach = brute_force_neighbours(x, np.ones(n, bool), radius + skin).sum(1).max()
    assert core < reach  # the slots below fit the radius's pairs, not the skin's
    k = int(core)
    got = build(_SKIN_GRID, jnp.asarray(x), active, k, radius, skin)
    assert not bool(got.with_skin) and not bool(got.neighbour_overflow)
    ref = brute_force_neighbours(x, np.ones(n, bool), radius)
    np.testing.assert_array_equal(_within(got.index, x, radius), ref)
    assert np.all(np.asarray(got.index) == n, where=~ref.any(1, keepdims=True))
    # Such lists are not carried: the next search builds anew.
    cache = NeighbourCache.of(got, jnp.asarray(x), active)
    assert not bool(cache.valid)
    again, kept = carried_search(
        _SKIN_GRID, jnp.asarray(x), active, k, radius, skin, cache
    )
    assert not bool(kept.valid)  # built again, with no more room than before
    np.testing.assert_array_equal(np.asarray(again.index), np.asarray(got.index))
    # With room for the skin, the lists hold its pairs and are carried.
    roomy = build(_SKIN_GRID, jnp.asarray(x), active, int(reach), radius, skin)
    assert bool(roomy.with_skin)
    np.testing.assert_array_equal(
        _within(roomy.index, x, radius + skin),
        brute_force_neighbours(x, np.ones(n, bool), radius + skin),
    )
    # Slots too few even for the radius's pairs: flagged as before.
    assert bool(
        build(
            _SKIN_GRID, jnp.asarray(x), active, k - 1, radius, skin
        ).neighbour_overflow
    )


def test_carried_lists_add_up_the_moves_since_their_search(rng):
    n, radius, skin = 300, 0.15, 0.03
    x0 = rng.uniform(0.1, 0.9, (n, 2))
    active = jnp.ones(n, bool)
    first = build(_SKIN_GRID, jnp.asarray(x0), active, 150, radius, skin)
    cache = NeighbourCache.of(first, jnp.asarray(x0), active)
    step = rng.normal(size=(n, 2))
    step *= 0.3 * skin / np.linalg.norm(step, axis=1, keepdims=True)

    def search(x, c):
        return carried_search(_SKIN_GRID, jnp.asarray(x), active, 150, radius, skin, c)

    # 0.3 skin from the search: carried, and the cache keeps the search's positions.
    nbrs, cache1 = search(x0 + step, cache)
    np.testing.assert_array_equal(np.asarray(nbrs.index), np.asarray(first.index))
    np.testing.assert_array_equal(np.asarray(cache1.position), x0)
    # Another 0.3 skin (0.6 in all, in random directions: pairs moved apart or
    # together by more than the skin): searched again there.
    x2 = x0 + 2 * step
    nbrs, cache2 = search(x2, cache1)
    new = build(_SKIN_GRID, jnp.asarray(x2), active, 150, radius, skin)
    np.testing.assert_array_equal(np.asarray(nbrs.index), np.asarray(new.index))
    np.testing.assert_allclose(np.asarray(cache2.position), x2)
    np.testing.assert_array_equal(
        _within(nbrs.index, x2, radius),
        brute_force_neighbours(x2, np.ones(n, bool), radius),
    )


def _sliding_layer(skin):
    """A lattice of 'water' (rows 1-8) over a fixed 'wall' row, spacing 0.05."""
    xs = np.arange(0.1, 0.9, 0.05)
    wall = np.stack(np.meshgrid(xs, [0.1]), -1).reshape(-1, 2)
    water = np.stack(np.meshgrid(xs[2:-2], 0.1 + 0.05 * np.arange(1, 9)), -1)
    return wall, water.reshape(-1, 2)


@pytest.mark.parametrize(
    "move, carried",
    [
        # Water sliding along the wall: pairs move by the water's move.
        ((0.9, 0.0), True),
        ((1.1, 0.0), False),
        # Water and wall shifted together far beyond half the skin (a frame
        # moving as a whole): no pair has moved.
        ((3.0, 2.0), True),
    ],
)
def test_lists_are_carried_while_no_pair_has_moved_by_the_skin(move, carried):
    radius, skin = 0.15, 0.03
    wall, water = _sliding_layer(skin)
    x0 = np.concatenate([wall, water])
    n = len(x0)
    active = jnp.ones(n, bool)
    first = build(_SKIN_GRID, jnp.asarray(x0), active, 150, radius, skin)
    cache = NeighbourCache.of(first, jnp.asarray(x0), active)
    x1 = x0.copy()
    moving = slice(len(wall), None) if move[1] == 0.0 else slice(None)
    x1[moving] += skin * np.asarray(move)
    got, _ = carried_search(
        _SKIN_GRID, jnp.asarray(x1), active, 150, radius, skin, cache
    )
    if carried:
        np.testing.assert_array_equal(np.asarray(got.index), np.asarray(first.index))
    else:
        new = build(_SKIN_GRID, jnp.asarray(x1), active, 150, radius, skin)
        np.testing.assert_array_equal(np.asarray(got.index), np.asarray(new.index))
    ref = brute_force_neighbours(x1, np.ones(n, bool), radius)
    np.testing.assert_array_equal(_within(got.index, x1, radius), ref)


@pytest.mark.parametrize("dim", [2, 3])
def test_carried_lists_never_miss_a_pair_under_random_smooth_moves(rng, dim):
    # Moves = a random translation + a random linear field + noise, at amplitudes
    # that straddle the skin: whenever the lists are kept, a brute-force search
    # finds no pair closer than the radius that they miss.
    n, radius, skin, grid = _unit_box_case(dim)
    x0 = rng.uniform(0.1, 0.9, (n, dim))
    active = rng.uniform(size=n) > 0.1
    first = build(grid, jnp.asarray(x0), jnp.asarray(active), 150, radius, skin)
    cache = NeighbourCache.of(first, jnp.asarray(x0), jnp.asarray(active))
    search = jax.jit(
        lambda x: carried_search(grid, x, jnp.asarray(active), 150, radius, skin, cache)
    )
    kept_beyond_half = searched = 0
    for _ in range(40):
        scale = skin * rng.uniform(0.2, 3.0)
        move = scale * (
            rng.normal(size=dim)
            + 0.5 * (x0 - 0.5) @ rng.normal(size=(dim, dim))
            + rng.uniform(0.0, 0.3) * rng.normal(size=(n, dim))
        )
        x1 = x0 + move
        got, _ = search(jnp.asarray(x1))
        kept = np.array_equal(np.asarray(got.index), np.asarray(first.index))
        largest = np.linalg.norm(move[active], axis=1).max()
        kept_beyond_half += kept and largest > skin / 2
        searched += not kept
        ref = brute_force_neighbours(x1, active, radius)
        np.testing.assert_array_equal(_within(got.index, x1, radius), ref)
    # Both outcomes were drawn, and lists were kept beyond the plain test's reach.
    assert kept_beyond_half > 0 and searched > 0


def test_lists_are_not_kept_after_a_non_finite_move():
    radius, skin = 0.15, 0.03
    wall, water = _sliding_layer(skin)
    x0 = np.concatenate([wall, water])
    active = jnp.ones(len(x0), bool)
    moved = jnp.zeros_like(jnp.asarray(x0)).at[5, 0].set(jnp.nan)
    assert not bool(
        lists_hold(_SKIN_GRID, jnp.asarray(x0), moved, active, radius, skin)
    )
    assert bool(
        lists_hold(
            _SKIN_GRID, jnp.asarray(x0), jnp.zeros_like(moved), active, radius, skin
        )
    )


def test_candidates_are_sized_for_fluid_filling_an_empty_part_of_the_domain():
    import jaxmps

    # A bed of three wall rows, nothing above it: the initial stencils hold few
    # particles, but fluid that later fills the box is a full lattice.
    l0 = 1.0
    bed = np.stack(np.meshgrid(np.arange(40.0), np.arange(3.0)), -1).reshape(-1, 2)
    scene = jaxmps.make_scene(bed, l0, ((-3.0, -3.0), (43.0, 30.0)))
    filled = np.stack(np.meshgrid(np.arange(40.0), np.arange(25.0)), -1)
    filled = filled.reshape(-1, 2) + 0.37  # off the cells' corners
    assert int(candidate_counts(scene.grid, bed).max()) < 27
    assert scene.grid.candidate_capacity >= 1.5 * 36  # cells of 1.2 l0: 6 x 6
    n = len(filled)
    got = build(
        scene.grid,
        jnp.asarray(filled),
        jnp.ones(n, bool),
        scene.max_neighbours,
        scene.r_e,
        scene.neighbour_skin,
    )
    assert not bool(got.cell_overflow) and bool(got.with_skin)
    np.testing.assert_array_equal(
        _within(got.index, filled, scene.r_e),
        brute_force_neighbours(filled, np.ones(n, bool), scene.r_e),
    )


@pytest.mark.parametrize("dim", [2, 3])
def test_default_slots_keep_the_skin_of_a_lattice_a_little_denser(dim):
    """`make_scene`'s default slots hold the skin's pairs of a regular lattice
    whose spacing shrank by 3 %, so that its lists can be carried (with 64 slots
    in 3-D, the lattice's 24 pairs at sqrt(6) l0 = 2.45 l0 entered the reach of
    r_e + skin = 2.4 l0 and every search fell back to the pairs within r_e)."""
    l0, side = 0.01, 8
    axes = [np.arange(side) * l0] * dim
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, dim)
    scene = jaxmps.make_scene(x, l0, (x.min(0) - 3 * l0, x.max(0) + 3 * l0))
    squeezed = x.mean(0) + 0.97 * (x - x.mean(0))
    active = jnp.ones(len(x), bool)
    nbrs = build(
        scene.grid,
        jnp.asarray(squeezed),
        active,
        scene.max_neighbours,
        scene.r_e,
        scene.neighbour_skin,
    )
    assert bool(nbrs.with_skin)
    assert not bool(nbrs.neighbour_overflow)
    # The reach does hold more than the lattice's own pairs (56 in 3-D).
    reach = scene.r_e + scene.neighbour_skin
    d = np.linalg.norm(squeezed[:, None] - squeezed[None], axis=-1)
    most = int(((d > 0) & (d < reach)).sum(1).max())
    assert most == (20 if dim == 2 else 80)
    assert most <= scene.max_neighbours
