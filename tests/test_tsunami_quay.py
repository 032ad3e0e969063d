"""The tsunami-over-a-quay scene (seed 000 chapters 4-5): its construction, its
wave, its refusals, and a 2-D run in which the wave lifts the ship onto the quay
(the trends against the seed are in validation/tsunami_quay.py)."""

import math

import equinox as eqx
import numpy as np
import pytest

import jaxmps

COARSE = dict(spacing=1.0)
SMALL_3D = dict(
    spacing=2.0,
    dim=3,
    sea_length=40.0,
    quay_length=30.0,
    ship_length=20.0,
    ship_beam=10.0,
    width=30.0,
    gauges=2,
    gauge_spacing=6.0,
    offshore_gauge=20.0,
)


def test_the_wave_is_the_simple_wave_of_its_height_and_froude_scales():
    """The inflow feeds depth h + eta at u = 2 (sqrt(g (h + eta)) - sqrt(g h)); at
    scale 1:100 lengths shrink 100 x and times and speeds 10 x."""
    full = jaxmps.scenes.tsunami_quay(**COARSE)
    h, eta, g = 12.0, 8.0, 9.81
    series = full.params.inflow
    assert float(np.max(series.depth)) == pytest.approx(h + eta, rel=1e-6)
    u = 2 * (math.sqrt(g * (h + eta)) - math.sqrt(g * h))
    assert float(np.max(series.velocity)) == pytest.approx(u, rel=1e-5)
    assert float(series.times[-1]) == pytest.approx(40.0)
    # The ship floats at its draft: density rho d / H.
    assert full.config["ship_density"] == pytest.approx(1000.0 * 4.0 / 8.0)
    model = jaxmps.scenes.tsunami_quay(scale=0.01, spacing=0.01)
    assert model.config["sea_depth"] == pytest.approx(0.12)
    assert float(model.params.inflow.times[-1]) == pytest.approx(4.0)
    assert float(np.max(model.params.inflow.velocity)) == pytest.approx(
        0.1 * u, rel=1e-4
    )
    assert model.t_end == pytest.approx(4.0)


@pytest.mark.parametrize("t_end", [40.0, 16.0, 60.0])
def test_the_pool_holds_what_the_wave_brings_up_to_t_end(t_end):
    """The inactive slots hold the volume fed up to `t_end` (the whole wave, 40 s,
    or less): a run of 16 s carries no slots for the water after it."""
    case = jaxmps.scenes.tsunami_quay(**COARSE, t_end=t_end)
    series = case.params.inflow
    t = np.linspace(0.0, t_end, 40001)
    q = np.interp(t, series.times, series.velocity * series.depth)
    brought = np.trapezoid(q, t) / 1.0**2
    pool = case.scene.capacity - int(case.state.active.sum())
    # 10 % spare and four columns of the inflow's height (h + eta + 2 l0 = 22 l0)
    assert brought <= pool <= 1.1 * brought + 4 * 22 + 1


@pytest.mark.parametrize("dim, l0", [(2, 0.02), (3, 0.05)])
def test_column_depth_reads_the_water_in_the_column_not_the_spray(dim, l0):
    """Still water 0.2 m deep: the column over a particle holds 0.2 / l0 of them,
    so it reads 0.2 m; one particle thrown 1 m above it adds l0 (the highest
    particle, `WaterLevel`, would read 1 m); a dry column reads 0."""
    case = jaxmps.scenes.hydrostatic(dim=dim, spacing=l0)
    state = case.state
    fluid = np.flatnonzero(np.asarray(state.kind) == int(jaxmps.Kind.FLUID))
    x = np.asarray(state.position)[fluid[0], :-1]
    at = jaxmps.scenes.ColumnDepth("depth", tuple(x), 0.0, l0)
    assert float(at(case.scene, state)) == pytest.approx(0.2, abs=1e-9)
    far = fluid[-1]  # a particle from another column, thrown over this one
    spray = state.position.at[far].set(np.append(x, 1.0))
    state = eqx.tree_at(lambda s: s.position, state, spray)
    assert float(at(case.scene, state)) == pytest.approx(0.2 + l0, abs=1e-9)
    high = jaxmps.scenes.WaterLevel("level", float(x[0]), 0.0, l0)
    assert float(high(case.scene, state)) == pytest.approx(1.0 + 0.5 * l0)
    dry = jaxmps.scenes.ColumnDepth("dry", tuple(x), 0.3, l0)
    assert float(dry(case.scene, case.state)) == 0.0
    # Between lattice columns (a quarter and a half spacing off along each
    # axis) the gauge still reads the still water's depth.
    for shift in (0.25, 0.5):
        off = jaxmps.scenes.ColumnDepth("off", tuple(x + shift * l0), 0.0, l0)
        assert float(off(case.scene, case.state)) == pytest.approx(0.2, abs=1e-9)


@pytest.mark.parametrize(
    "settings, match",
    [
        ({"ship_gap": -5.0}, "ship_gap"),  # overlapping the quay
        ({"tsunami_height": -2.0}, "tsunami_height"),
        ({"ship_draft": 12.0, "ship_height": 16.0}, "sea bed"),
        ({"ship_draft": 9.0}, "ship_height"),
        ({"building_depth": 9.0, "building_distance": 95.0}, "quay's end"),
        ({"ship_body": "steel"}, "ship_body"),
        ({"ship_gap": 0.4}, "ship_gap=0.4 m is under half the particle spacing"),
        ({"quay_crest": 0.3}, "quay_crest"),
        ({"sea_length": 20.0}, "inflow boundary"),
        ({"offshore_gauge": 70.0}, "offshore_gauge"),
        ({"reservoir_length": 50.0}, "reservoir_depth"),
        ({"reservoir_length": 50.0, "reservoir_depth": 10.0}, "exceed sea_depth"),
        ({"building_depth": 9.0, "pressure_gauges": 20}, "pressure_gauges"),
    ],
)
def test_bad_settings_are_refused_naming_them(settings, match):
    with pytest.raises(ValueError, match=match):
        jaxmps.scenes.tsunami_quay(**{**COARSE, **settings})


def test_a_wave_above_the_inflow_boundary_is_refused_before_the_run():
    """Params changed after building (a higher wave than the scene was built
    for) cannot be fed by its boundary."""
    import equinox as eqx

    case = jaxmps.scenes.tsunami_quay(**COARSE)
    higher = eqx.tree_at(
        lambda p: p.inflow.depth, case.params, case.params.inflow.depth * 2
    )
    with pytest.raises(ValueError, match="inflow.depth"):
        jaxmps.simulate(case.scene, higher, case.state, 2, 2)


@pytest.mark.slow
def test_the_wave_lifts_the_ship_onto_the_quay_and_the_inflow_balances():
    """2-D at l0 = 1 m (8 m wave on a 12 m sea, quay 2 m above it): within 13 s
    the ship is carried over the quay edge, its keel above the quay top, faster
    than 4 m/s; until water reaches the outflow the fluid gained equals the
    discharge fed, integrated (within 2 %). The boundary is a piston here, which
    feeds the series' discharge whatever comes back to it (an absorbing one
    answers the water in front, `test_open_boundaries`)."""
    case = jaxmps.scenes.tsunami_quay(
        **COARSE, t_end=13.0, inflow_absorbing=False
    )  # its pool: to 13 s
    observe = jaxmps.scenes.observe_probes(case.probes)
    times = np.arange(1, 14) * 1.0
    run = jaxmps.simulate(
        case.scene, case.params, case.state, times=times, observe=observe
    )
    saved = {k: np.asarray(v) for k, v in run.saved.items()}
    c = case.config
    edge, quay_top = c["quay_edge"], c["sea_depth"] + c["quay_crest"]
    assert saved["ship_x"][-1] - 0.5 * c["ship_beam"] > edge
    assert saved["ship_z"][-1] - 0.5 * c["ship_height"] > quay_top
    assert saved["ship_u"].max() > 4.0
    assert saved["quay_depth_1"][-1] > 2.0  # the quay is flooded
    series = case.params.inflow
    t = np.linspace(0.0, 13.0, 13001)
    fed = np.interp(t, series.times, series.velocity) * np.interp(
        t, series.times, series.depth
    )
    gained = saved["fluid_count"][-1] - int(
        (case.state.active & (case.state.kind == int(jaxmps.Kind.FLUID))).sum()
    )
    assert gained == pytest.approx(np.trapezoid(fed, t), rel=0.02)


@pytest.mark.slow
def test_three_d_scene_feeds_the_channel_and_floats_the_ship():
    """3-D: the inflow sheet spans the channel, feeds it, and nothing leaves the
    channel sideways (a smoke run at l0 = 2 m, the wave rising over 3 s: in 2 s
    the boundary travels 3.95 m, feeding one sheet)."""
    case = jaxmps.scenes.tsunami_quay(**SMALL_3D, rise_time=3.0)
    observe = jaxmps.scenes.observe_probes(case.probes)
    run = jaxmps.simulate(
        case.scene, case.params, case.state, times=[2.0], observe=observe
    )
    before = int((case.state.active & (case.state.kind == 0)).sum())
    assert float(run.saved["fluid_count"][-1]) > before
    fluid = np.asarray(run.state.active & (run.state.kind == 0))
    y = np.asarray(run.state.position)[fluid, 1]
    assert y.min() > 0 and y.max() < case.config["width"]
    # The ship still floats near its draft (the wave has not reached it yet).
    keel = float(run.saved["ship_z"][-1]) - 0.5 * case.config["ship_height"]
    assert keel == pytest.approx(case.config["sea_depth"] - 4.0, abs=2.0)


def test_dam_break_variant_builds_the_reservoir_and_its_gauges_read_dry_as_zero():
    """With a reservoir the wave is a dam break: no inflow, the reservoir's water
    behind the gate, and the building's gauges read zero while it is dry (the
    dry walls' own pressure discounted)."""
    flume = dict(
        sea_length=4.5,
        sea_depth=0.2,
        quay_crest=0.02,
        quay_length=1.5,
        ship=False,
        building_depth=0.12,
        building_height=0.4,
        building_distance=0.12,
        pressure_spacing=0.02,
        reservoir_length=1.0,
        reservoir_depth=0.5,
        offshore_gauge=1.0,
        gauge_spacing=0.06,
        gauges=1,
        spacing=0.04,
    )
    case = jaxmps.scenes.tsunami_quay(**flume)
    assert case.scene.inflow is None and case.params.inflow is None
    fluid = np.asarray(case.state.kind == int(jaxmps.Kind.FLUID)) & np.asarray(
        case.state.active
    )
    x = np.asarray(case.state.position)[fluid, 0]
    c = case.config  # lengths on the lattice (0.5 m is 12 rows of 4 cm)
    assert int(np.sum(x < 0)) == round(
        c["reservoir_length"] * c["reservoir_depth"] / 0.04**2
    )
    assert int(np.sum(x > 0)) == round(c["sea_length"] * c["sea_depth"] / 0.04**2)
    observe = jaxmps.scenes.observe_probes(case.probes)
    run = jaxmps.simulate(case.scene, case.params, case.state, 5, 5, observe)
    for k in (1, 2, 3):
        assert float(run.saved[f"building_pressure_{k}"][-1]) == 0.0
    assert float(run.saved["building_force"][-1]) == 0.0


def test_elastic_ship_floats_at_its_draft_under_the_coupling_step_limit():
    """`ship_body="elastic"`: the largest step is cut to the elastic coupling
    limit (0.5 l0 / c_s) so the case runs as built, and the ship floats with
    its centre at the still-water level (draft 4 m of 8 m) within l0/4."""
    case = jaxmps.scenes.tsunami_quay(**COARSE, ship_body="elastic")
    c_s = jaxmps.bodies.shear_speed(1.7e7, 0.3, case.config["ship_density"])
    assert float(case.params.dt) <= 0.5 * 1.0 / c_s
    observe = jaxmps.scenes.observe_probes(case.probes)
    run = jaxmps.simulate(
        case.scene, case.params, case.state, times=[0.5], observe=observe
    )
    assert float(run.saved["ship_z"][-1]) == pytest.approx(12.0, abs=0.25)
