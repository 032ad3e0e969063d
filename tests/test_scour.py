"""The flume's movable bed of DEM grains and seed 002's local scour scene: the
packed bed in its pit, the spin-up with the grains feeling no flow, the scour
hole's probes, and erosion that follows the grains' mobility."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import Kind

jax.config.update("jax_enable_x64", True)

# Seed 002's Case 2-2 groundsill at l0 = d = 5 mm, its grains over 0.2 m.
COARSE = dict(spacing=0.005, movable_length=0.2, movable_depth=0.04)


@pytest.fixture(scope="module")
def case():
    return jaxmps.scenes.local_scour(**COARSE, release_time=0.1, t_end=0.5)


def test_the_packed_bed_fills_its_pit_clear_of_walls_and_water(case):
    l0 = case.config["spacing"]
    x0, x1, floor = case.config["movable_stretch"]
    assert x0 == pytest.approx(case.config["apron_end"])
    assert x1 - x0 == pytest.approx(0.2) and floor == pytest.approx(-0.02 - 0.04)
    position = np.asarray(case.state.position)
    kind = np.asarray(case.state.kind)
    active = np.asarray(case.state.active)
    index = np.asarray(case.state.grains.index)
    grains = position[index]
    # All attached to the bed at the start: walls to the fluid.
    assert np.all(np.asarray(case.state.grains.attached))
    assert np.all(kind[index] == int(Kind.WALL))
    # Seed 002's hexagonal packing inside the pit: rows sqrt(3)/2 d apart, d
    # between grains, every other row shifted by d/2 (one grain fewer).
    assert np.all((grains[:, 0] > x0) & (grains[:, 0] < x1) & (grains[:, 1] > floor))
    rows = int(np.floor((0.04 - l0) / (0.5 * np.sqrt(3) * l0) + 1e-9)) + 1
    assert len(index) == rows * 40 - rows // 2
    others = np.ones(len(position), bool)
    others[index] = False
    others &= active
    d = np.min(
        np.linalg.norm(grains[:, None] - position[others][None], axis=-1), axis=1
    )
    # Touching the pit's walls at most (distance l0), never inside them; the water
    # laid 0.9 l0 clear at least.
    assert d.min() >= l0 * (1 - 1e-9)
    fluid = active & (kind == int(Kind.FLUID))
    near = np.min(
        np.linalg.norm(grains[:, None] - position[fluid][None], axis=-1), axis=1
    )
    assert near.min() >= 0.9 * l0 * (1 - 1e-9)
    # The inflow's pool holds 1.5 times the water that fills the pit, should the
    # flow scour it empty, more than over a fixed bed.
    fixed = jaxmps.scenes.local_scour(**{**COARSE, "movable_length": 0.0})
    extra = case.config["pool"] - fixed.config["pool"]
    assert extra >= 1.5 * (x1 - x0) * 0.04 / l0**2 - 2
    assert {p.name for p in case.probes} >= {"scour_depth", "scour_length"}
    assert "local_scour" in jaxmps.scenes.available()


def _lowered(case, cut):
    """The case's state with the bed's grains in `cut` (a mask) taken out of it
    (detached, touching nothing)."""
    gs = case.state.grains
    grains = dataclasses.replace(
        gs,
        attached=gs.attached & ~jnp.asarray(cut),
        contact_count=jnp.where(jnp.asarray(cut), 0, gs.contact_count),
    )
    return dataclasses.replace(case.state, grains=grains)


def test_the_scour_probes_measure_a_hole_cut_by_hand(case):
    """A rectangular hole cut in the bed: its depth in whole packing rows, its
    length in bins; a hole shallower than one grain is none."""
    l0 = case.config["spacing"]
    grains = np.asarray(case.state.position)[np.asarray(case.state.grains.index)]
    top = grains[:, 1].max()
    x0 = case.config["movable_stretch"][0]
    rise = 0.5 * np.sqrt(3) * l0
    probes = {p.name: p for p in case.probes}
    for rows, (a, b) in [(3, (0.05, 0.09)), (5, (0.0, 0.04)), (1, (0.1, 0.12))]:
        cut = (grains[:, 0] > x0 + a) & (grains[:, 0] < x0 + b)
        cut &= grains[:, 1] > top - (rows - 0.5) * rise
        state = _lowered(case, cut)
        depth = float(probes["scour_depth"](case.scene, state))
        length = float(probes["scour_length"](case.scene, state))
        if rows * rise <= l0:
            assert depth == pytest.approx(rows * rise, abs=1e-9) and length == 0.0
            continue
        # The deepest bin lost `rows` rows; its top row may sit d/2 sideways.
        assert depth == pytest.approx(rows * rise, abs=1e-9)
        # Bins of 2 l0: the cut's width within a bin at either end.
        assert abs(length - (b - a)) <= 2 * 2 * l0 + 1e-9


@pytest.fixture(scope="module")
def runs(case):
    """The coarse scene 0.1 s held and 0.4 s free, with its grains of the seed's
    R = 1.25 and of a light R = 0.1 (a mobility 12.5 times the seed's)."""
    times = np.arange(1, 11) * 0.05
    out = {}
    for name, density in (("seed", 2250.0), ("light", 1100.0)):
        # The seed's stiffness rule for the grain's submerged mass at this dt.
        mass = (density - 1000.0) * jaxmps.bodies.sphere_volume(0.005)
        stiffness = jaxmps.bodies.rule_stiffness(mass, float(case.params.dt))
        params = eqx.tree_at(
            lambda p: (p.grains.density, p.grains.stiffness),
            case.params,
            tuple(jnp.asarray(v, case.params.dt.dtype) for v in (density, stiffness)),
        )
        probes = jaxmps.scenes.observe_probes(case.probes)
        out[name] = jaxmps.simulate(
            case.scene,
            params,
            case.state,
            times=times,
            observe=lambda s, st: (jaxmps.frame(s, st), probes(s, st)),
        )
    return times, out


def test_the_grains_feel_no_flow_and_stay_placed_until_release(case, runs):
    times, out = runs
    frames, probes = out["seed"].saved
    held = times < 0.1 - 1e-9
    force = np.asarray(frames.bodies["fluid_force"])
    assert np.all(force[held] == 0.0)
    assert np.abs(force[~held]).max() > 0.0
    # Settling under their own weight before it detaches none and digs no hole.
    assert np.all(np.asarray(frames.bodies["attached"])[held])
    assert np.all(np.asarray(probes["scour_depth"])[held] == 0.0)


def test_the_flow_erodes_light_grains_where_the_seed_grains_hold(runs):
    """At l0 = d = 5 mm the seed's R = 1.25 grains are too coarse for this flow
    to move (a Shields number of about 0.03); grains 12.5 times lighter are
    carried off and the bed is lowered by grains, not by settling. Measured:
    none detached and 0.1 mm of settling against 345 detached and a bed lowered
    by up to 1.9 cm."""
    times, out = runs
    free = times > 0.1
    detached, depth = {}, {}
    for name, run in out.items():
        frames, probes = run.saved
        assert run.result == jaxmps.Result.successful
        detached[name] = int((~np.asarray(frames.bodies["attached"][-1])).sum())
        depth[name] = np.asarray(probes["scour_depth"])[free]
    l0 = 0.005
    assert detached["seed"] <= 2 and depth["seed"].max() < 0.1 * l0
    assert detached["light"] > 100
    assert depth["light"].max() > 3 * l0 and depth["light"][-1] > l0


def test_the_stiffness_is_the_seeds_rule_at_the_step(case):
    """With the explicit solver the bed's stiffness is seed 002's rule (12.9 N/m
    at its 1 mm and 5e-5 s), so that one DEM sub-step keeps its contacts."""
    mass = 1250.0 * jaxmps.bodies.sphere_volume(0.005)
    rule = jaxmps.bodies.rule_stiffness(mass, float(case.params.dt))
    assert float(case.params.grains.stiffness) == pytest.approx(rule, rel=1e-12)
    assert case.scene.grains.substeps == 1
    seed = jaxmps.bodies.seed_contact_parameters(0.001, 1.25, 5e-5)
    assert seed["k_n"] == pytest.approx(12.9, rel=2e-3)


@pytest.mark.parametrize(
    "settings, match",
    [
        ({"movable_depth": 0.004}, "movable_depth=0.005 m leaves less than two"),
        ({"movable_start": 0.01}, r"must lie below the crest \(x >= crest_length"),
        ({"movable_length": 1.2}, "end at least one spacing before the bed's end"),
        ({"release_time": -1.0}, "release_time must be finite and >= 0"),
        ({"stiffness": -1.0}, "stiffness must be"),
    ],
)
def test_bad_movable_beds_are_refused_by_name(settings, match):
    with pytest.raises(ValueError, match=match):
        jaxmps.scenes.local_scour(**{**COARSE, **settings})


def test_an_unknown_stiffness_rule_is_refused(case):
    position = np.array([[0.05, 0.0025], [0.05, 0.05]])
    scene = jaxmps.make_scene(position, 0.005, ([0, -0.01], [0.1, 0.1]))
    params = jaxmps.make_params(2, dt=1e-4)
    state = jaxmps.make_state(scene, position, [0, 1])
    mask = np.array([True, False])
    with pytest.raises(ValueError, match="stiffness='soft': give a number of N/m"):
        jaxmps.add_grains(
            scene,
            params,
            state,
            mask,
            friction=0.5,
            restitution=0.1,
            density=2650.0,
            stiffness="soft",
        )
    with pytest.raises(ValueError, match=r"grains.release_time must be >= 0"):
        jaxmps.add_grains(
            scene,
            params,
            state,
            mask,
            friction=0.5,
            restitution=0.1,
            density=2650.0,
            release_time=-0.5,
        )


def test_grains_carried_out_leave_by_the_outflow_and_keep_their_slots(case):
    """A grain past the outflow plane (over the free overfall) is retired, not
    lost out of the domain, and the inflow, feeding from the pool's lowest
    slots first, never takes its slot (which comes before the pool's)."""
    gs = case.state.grains
    slot = int(gs.index[0])
    at = jnp.asarray([case.scene.outflow.position + 0.002, -0.03])
    grains = dataclasses.replace(
        gs, attached=gs.attached.at[0].set(False), origin=gs.origin.at[0].set(at)
    )
    state = dataclasses.replace(
        case.state,
        position=case.state.position.at[slot].set(at),
        kind=case.state.kind.at[slot].set(int(Kind.SEDIMENT)),
        grains=grains,
    )
    out = jaxmps.simulate(case.scene, case.params, state, times=[0.05])
    assert out.result == jaxmps.Result.successful
    assert not bool(out.state.active[slot])
    assert int(out.state.kind[slot]) == int(Kind.SEDIMENT)
    # The inflow fed meanwhile (the speed 0.49 m/s moves it 5 spacings).
    pool = np.arange(case.scene.capacity) >= int(np.asarray(state.active).sum())
    assert np.asarray(out.state.active)[pool].sum() > 0
