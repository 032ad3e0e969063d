"""Bodies held still until a release time (seed 002 spins its flumes up with the
blocks frozen), the washout probe, and the `block_washout` scene: seed 002's
fixed-bed groundsill with the scour hole its bed lowering implies."""

import dataclasses
import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps

jax.config.update("jax_enable_x64", True)

# A block of 5 x 5 particles on a floor tilted by 40 degrees, mu = 0.5: it
# slides at g (sin 40 - 0.5 cos 40) = 2.548 m/s^2 once free.
# The seed's blocks at l0 = 5 mm (§8.3: 2.0 x 1.5 cm, no gaps).
COARSE = dict(spacing=0.005, block_length=0.02, block_height=0.015, block_gap=0.0)
TILT = dict(angle=40.0, spacing=0.02, block_size=0.1, floor_length=0.6, settle=0.0)


def _released(case, release):
    return eqx.tree_at(
        lambda p: p.rigid.release_time,
        case.params,
        jnp.asarray(release, case.params.dt.dtype),
        is_leaf=lambda x: x is None,
    )


def test_held_block_stays_until_its_release_then_slides_by_coulomb():
    case = jaxmps.scenes.friction_tilt(**TILT)
    params = _released(case, [0.1])
    times = np.linspace(0.02, 0.3, 15)
    out = jaxmps.simulate(
        case.scene,
        params,
        case.state,
        times=times,
        observe=jaxmps.scenes.observe_probes(case.probes),
    )
    x = np.asarray(out.saved["block_x"])
    x0 = float(case.state.rigid.centre[0, 0])
    held = times < 0.1 - 1e-9
    assert np.all(x[held] == x0)  # not a round-off's worth of motion
    a = 9.81 * (np.sin(np.radians(40)) - 0.5 * np.cos(np.radians(40)))
    free = times > 0.15
    theory = 0.5 * a * (times[free] - 0.1) ** 2
    # measured: within 0.1 % (0.05100 m against 0.05097 m at 0.3 s)
    np.testing.assert_allclose(x[free] - x0, theory, rtol=0.01)


def test_release_times_sweep_as_one_batch():
    """Per member, per body: the batch gives what each run gives alone."""
    case = jaxmps.scenes.friction_tilt(**TILT, t_end=0.2)
    release = np.array([[0.05], [0.15]])
    with pytest.raises(ValueError, match="rigid.release_time is not set"):
        jaxmps.sweep(case, {"rigid.release_time": release}, times=[0.2])
    case = eqx.tree_at(lambda c: c.params, case, _released(case, [0.0]))
    batch = jaxmps.sweep(case, {"rigid.release_time": release}, times=[0.2])
    for member, r in enumerate(release):
        alone = jaxmps.simulate(
            case.scene,
            _released(case, r),
            case.state,
            times=[0.2],
            observe=jaxmps.scenes.observe_probes(case.probes),
        )
        np.testing.assert_allclose(
            np.asarray(batch.saved["block_x"])[member],
            np.asarray(alone.saved["block_x"]),
            rtol=1e-12,
        )
    moved = np.asarray(batch.saved["block_x"])[:, -1] - float(
        case.state.rigid.centre[0, 0]
    )
    assert moved[0] > 3 * moved[1] > 0  # released earlier, further down


def test_release_time_refusals():
    case = jaxmps.scenes.friction_tilt(**TILT)
    with pytest.raises(ValueError, match="release_time must be finite and >= 0"):
        jaxmps.scenes.flume(
            crest_length=0.1,
            reach_length=0.2,
            block_rows=2,
            release_time=-1.0,
        )
    with pytest.raises(ValueError, match=r"Params.rigid.release_time has shape \(2,\)"):
        jaxmps.simulate(case.scene, _released(case, [0.1, 0.2]), case.state, n_steps=1)
    with pytest.raises(ValueError, match=r"Params.rigid.release_time must be >= 0"):
        dataclasses.replace(case.params.rigid, release_time=[-0.1])
    scene, params, state = _bare_block()
    owner = np.where(np.arange(scene.capacity) < 9, 0, -1)
    with pytest.raises(ValueError, match="release_time must be >= 0"):
        jaxmps.add_rigid_bodies(
            scene, params, state, owner, density=2.0e3, release_time=-2
        )


def _bare_block():
    """A 3 x 3 block of particles in an empty box (no bodies yet)."""
    l0 = 0.1
    block = jaxmps.geometry.block([0.0, 0.0], [0.3, 0.3], l0)
    walls, wall_kind = jaxmps.geometry.tank([-1.0, -1.0], [1.0, 1.0], l0)
    position = np.concatenate([block, walls])
    kind = np.concatenate([np.zeros(len(block), int), wall_kind])
    scene = jaxmps.make_scene(position, l0, ([-2, -2], [2, 2]))
    params = jaxmps.make_params(2, dt=1e-3)
    return scene, params, jaxmps.make_state(scene, position, kind)


def test_scour_hole_follows_the_bed_lowering_between_the_measured_holes():
    holes = jaxmps.scenes.MEASURED_HOLES
    for drop, hole in holes.items():
        np.testing.assert_allclose(jaxmps.scenes.scour_hole(drop), hole)
    np.testing.assert_allclose(jaxmps.scenes.scour_hole(0.03), (0.145, 0.057, 0.0105))
    # held at the nearer measured hole outside the measured range
    np.testing.assert_allclose(jaxmps.scenes.scour_hole(0.0), holes[0.02])
    np.testing.assert_allclose(jaxmps.scenes.scour_hole(0.06), holes[0.04])


def test_block_washout_is_seed_002s_fixed_bed_case():
    case = jaxmps.scenes.block_washout(bed_lowering=0.04, release_time=1.0, t_end=2.0)
    c, l0 = case.config, 0.0025
    # the seed's blocks at 2.5 mm: 1.75 x 1.25 cm, 2597 kg/m^3 (the experiment's
    # 14.2 g over 2.5 cm of width), 16 rows 2.5 mm apart
    assert (c["block_length"], c["block_height"], c["block_gap"]) == pytest.approx(
        (0.0175, 0.0125, 0.0025)
    )
    assert c["block_density"] == pytest.approx(2597, rel=1e-3)
    np.testing.assert_allclose(case.params.rigid.density, c["block_density"])
    np.testing.assert_allclose(case.params.rigid.release_time, np.full(16, 1.0))
    # fed at the critical depth of q = 0.006 m^2/s (1.54 cm), on the lattice
    assert c["inflow_depth"] == pytest.approx(0.015)
    # Delta H = 4 cm: Case 3-3's hole, the last block's whole face exposed
    assert c["scour_length"] == pytest.approx(0.1)
    assert c["scour_exposure"] == pytest.approx(c["block_height"])
    profile = jaxmps.scenes._flume_bed.bed_profile(
        c, c["bed_length"], -(jaxmps.geometry.layers_for(case.scene.r_e / l0) + 1) * l0
    )
    end = c["apron_end"] + 16 * 0.02  # the first row one gap below the apron
    assert c["protection_end"] == pytest.approx(end)
    assert profile.height(end + 0.05) == pytest.approx(-0.02 - 0.05)  # deepest
    assert profile.height(1.9) == pytest.approx(-0.02 - 0.04)  # lowered bed
    # the blocks are the flume's PMS bodies; none has moved at the start
    names = [p.name for p in case.probes]
    assert "block15_x" in names and "blocks_out" in names
    out = jaxmps.scenes.observe_probes(case.probes)(case.scene, case.state)
    assert float(out["blocks_out"]) == 0.0
    # Delta H = 2 cm: Case 3-2's hole, 0.8 cm exposed (3 spacings on this lattice)
    gentle = jaxmps.scenes.block_washout(bed_lowering=0.02, t_end=1.0)
    assert gentle.config["scour_exposure"] == pytest.approx(0.0075)
    assert gentle.config["scour_length"] == pytest.approx(0.19)


def test_blocks_out_counts_the_blocks_that_left_their_place():
    case = jaxmps.scenes.block_washout(
        **COARSE,
        block_rows=4,
        t_end=1.0,
    )
    probe = next(p for p in case.probes if p.name == "blocks_out")
    centre = case.state.rigid.centre
    state = eqx.tree_at(
        lambda s: s.rigid.centre,
        case.state,
        centre.at[3, 0].add(0.021).at[2, 1].add(0.019).at[1, 0].add(-0.03),
    )
    assert float(probe(case.scene, state)) == 2.0  # 2.1 cm and 3 cm > 2 cm; 1.9 not


@pytest.mark.parametrize("spacing", [0.004, 0.0075, 0.01])
def test_block_washout_builds_its_rows_at_a_coarser_spacing(spacing):
    # The gaps between the blocks are built at least one spacing wide; the
    # reach that holds them must be measured the same way.
    case = jaxmps.scenes.block_washout(spacing=spacing)
    x = np.asarray(case.state.rigid.centre[:, 0])
    length = case.config["block_length"]
    assert len(x) == 16
    assert np.all(np.diff(x) >= length + spacing - 1e-9)


def test_block_washout_refuses_what_flume_refuses():
    with pytest.raises(ValueError, match="Unknown parameter.*'block_washout'"):
        jaxmps.scenes.block_washout(tail_length=0.3)
    with pytest.raises(ValueError, match="bed_length"):
        jaxmps.scenes.block_washout(bed_length=1.0)
    with pytest.raises(ValueError, match="release_time must be"):
        jaxmps.scenes.block_washout(release_time=-5.0)


def test_critical_feed_carries_each_discharge_through_whole_rows():
    case = jaxmps.scenes.block_washout(discharge=0.012, block_rows=2, t_end=1.0)
    assert case.config["inflow_depth"] == pytest.approx(0.025)  # h_c 2.45 cm
    for q, rows in ((0.006, 6), (0.009, 8), (0.012, 10)):  # h_c 1.54, 2.02, 2.45 cm
        velocity, depth = jaxmps.scenes.critical_feed(case, q)
        assert depth == pytest.approx(rows * 0.0025)
        assert velocity * depth == pytest.approx(q)
    with pytest.raises(ValueError, match="build it for the largest discharge"):
        jaxmps.scenes.critical_feed(case, 0.02)


def test_a_stored_config_rebuilds_the_case():
    """A run file's config holds derived values beside the settings (the
    flume's `apron_end`, the hole): a restart rebuilds from the settings."""
    case = jaxmps.scenes.block_washout(
        **COARSE,
        block_rows=3,
        release_time=0.5,
        t_end=1.0,
    )
    config = json.loads(jaxmps.io._hdf5.config_json(case.config))
    with pytest.raises(ValueError, match="Unknown parameter"):
        jaxmps.scenes.build("block_washout", **config)
    settings = jaxmps.scenes.stored_settings("block_washout", config)
    again = jaxmps.scenes.build("block_washout", **settings)
    np.testing.assert_array_equal(again.state.position, case.state.position)
    np.testing.assert_array_equal(again.params.rigid.release_time, [0.5] * 3)


# Two of the seed's §8.3 blocks (2 x 1 cm at 5 mm) on a short movable bed of its
# Method B grains (5 mm, 1250 kg/m^3 after the similarity scaling, k_n = 323 N/m).
ON_GRAINS = dict(
    spacing=0.005,
    apron_length=0.1,
    block_rows=2,
    block_length=0.02,
    block_height=0.01,
    block_gap=0.0,
    scour_length=0.0,
    scour_depth=0.0,
    scour_exposure=0.0,
    reach_length=0.04,
    transition_length=0.05,
    movable_length=0.1,
    movable_depth=0.03,
    bed_lowering=0.01,
    bed_length=0.3,
    grain_density=1250.0,
    stiffness=323.0,
)


@pytest.fixture(scope="module")
def on_grains():
    return jaxmps.scenes.block_washout(**ON_GRAINS, release_time=0.05, t_end=0.15)


def test_blocks_over_a_movable_bed_rest_on_its_grains(on_grains):
    """The pit is deepened by whole spacings until a row of the packed bed ends
    within 0.134 l0 under the blocks' recess, and the blocks are lowered by the
    rest: no gap under them for the bed to settle into, and no grain inside a
    block or cut by the last block's downstream face."""
    case, l0 = on_grains, ON_GRAINS["spacing"]
    x0, x1, floor = case.config["movable_stretch"]
    depth = -0.02 - floor
    assert depth >= ON_GRAINS["movable_depth"] - 1e-12
    assert depth <= ON_GRAINS["movable_depth"] + 6 * l0 + 1e-12
    assert round(floor / l0, 9) == round(floor / l0)  # on the lattice
    position = np.asarray(case.state.position)
    grains = position[np.asarray(case.state.grains.index)]
    body = np.asarray(case.state.rigid.body)
    member = np.asarray(case.state.kind) == int(jaxmps.Kind.RIGID)
    for b in range(ON_GRAINS["block_rows"]):
        block = position[member & (body == b)]
        distance = np.linalg.norm(block[:, None] - grains[None], axis=-1)
        assert distance.min() >= l0 * (1 - 1e-9)
        below = np.abs(grains[:, 0] - block[:, 0].mean()) < 0.5 * 0.02
        gap = (block[:, 1].min() - 0.5 * l0) - (grains[below, 1].max() + 0.5 * l0)
        assert 0.0 <= gap <= 1e-9 * l0  # resting, not hanging
        sink = -0.02 - 0.01 - (block[:, 1].min() - 0.5 * l0)
        assert 0.0 <= sink < 0.134 * l0
    # Each grain lies wholly under the bed beside the blocks (the reach at the
    # apron's level) or under the blocks.
    end = case.config["protection_end"]
    beside = (grains[:, 0] + 0.5 * l0 > end + 1e-9) & (grains[:, 0] < x0 + 0.15)
    assert np.all(grains[beside, 1] + 0.5 * l0 <= -0.02 + 1e-9)
    straddling = np.abs(grains[:, 0] - end) < 0.5 * l0 - 1e-9
    assert np.all(grains[straddling, 1] + 0.5 * l0 <= -0.03 + 1e-9)


def test_blocks_released_on_grains_stay_where_they_rest(on_grains):
    """Released onto the packed bed 0.05 s into the flow, each block stays within
    0.25 l0 and 0.01 rad over the next 0.1 s. Measured: 0.95 mm (the last row,
    sliding against its downstream grains), 0.05 mm and 3e-4 rad; before the
    bed was laid flush and the grains' contact with bodies went by distance,
    the blocks left at 0.5-1.1 m/s, spinning (a grain settling into the gap at
    the last block's foot, read as a wall plane 0.6 l0 away)."""
    case, l0 = on_grains, ON_GRAINS["spacing"]
    times = np.round(np.arange(1, 16) * 0.01, 6)
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=times,
        observe=jaxmps.scenes.observe_probes(case.probes),
    )
    centre = np.asarray(case.state.rigid.centre)
    for b in range(ON_GRAINS["block_rows"]):
        x = np.asarray(out.saved[f"block{b}_x"]) - centre[b, 0]
        y = np.asarray(out.saved[f"block{b}_y"]) - centre[b, 1]
        angle = np.asarray(out.saved[f"block{b}_angle"])
        held = times < 0.05 - 1e-9
        assert np.all(x[held] == 0.0) and np.all(y[held] == 0.0)
        assert np.max(np.hypot(x, y)) < 0.25 * l0
        assert np.max(np.abs(angle)) < 0.01
