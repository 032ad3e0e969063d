"""Inflow/outflow on the fixed-capacity pool (seed 000 §2.11, seed 002 §2.8, §3)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps


def _run(case, t):
    """Run to `t`, saving every 10 of the largest steps."""
    obs = jaxmps.scenes.observe_probes(case.probes)
    save = 10 * float(case.params.dt)
    times = save * np.arange(1, int(t / save) + 1)
    return jaxmps.simulate(
        case.scene, case.params, case.state, times=times, observe=obs
    )


def test_inflow_particle_count_matches_discharge_on_dry_bed():
    """Particles entering over T equal u h T / l0^2 within one column (2-D)."""
    l0 = 0.0075
    case = jaxmps.scenes.flume(spacing=l0, bed_length=0.6, initial_fill=False)
    tr = _run(case, 0.2)
    u = float(case.params.inflow.velocity)
    h = case.config["inflow_depth"]
    rows = round(h / l0)
    t = np.asarray(tr.saved["time"])
    count = np.asarray(tr.saved["fluid_count"])
    expected = u * h * t / l0**2
    assert np.all(np.abs(count - expected) <= rows)
    # The pool shrank by exactly what entered; nothing was created out of thin air.
    assert int(tr.state.active.sum()) == int(case.state.active.sum()) + int(count[-1])


@pytest.mark.slow
def test_flume_mass_balance_at_steady_state():
    """Storage change over 1 s of steady flow within 2 % of the inflow (measured
    0.5 %): what enters leaves over the free overfall."""
    l0 = 0.0075
    case = jaxmps.scenes.flume(spacing=l0, bed_length=0.4, t_end=3.6)
    tr = _run(case, 3.6)
    t = np.asarray(tr.saved["time"])
    count = np.asarray(tr.saved["fluid_count"])
    early = (t > 2.4) & (t < 2.6)
    late = t > 3.4
    stored = count[late].mean() - count[early].mean()
    entered = (
        float(case.params.inflow.velocity)
        * case.config["inflow_depth"]
        * (t[late].mean() - t[early].mean())
        / l0**2
    )
    assert abs(stored) / entered <= 0.02
    # Depth stays near the inflow depth on the supercritical bed.
    level = np.asarray(tr.saved["level_middle"])[t > 2.4].mean()
    assert level == pytest.approx(case.config["inflow_depth"], rel=0.2)


def test_pool_exhaustion_is_reported():
    case = jaxmps.scenes.flume(
        spacing=0.0075, bed_length=0.3, initial_fill=False, pool=8
    )
    obs = jaxmps.scenes.observe_probes(case.probes)
    tr = jaxmps.simulate(case.scene, case.params, case.state, 60, 60, obs, throw=False)
    assert tr.result == jaxmps.Result.pool_exhausted
    with pytest.raises(Exception, match="pool"):
        jaxmps.simulate(case.scene, case.params, case.state, 60, 60, obs)


def test_inflow_params_must_match_scene():
    case = jaxmps.scenes.flume(spacing=0.0075, bed_length=0.3)
    plain = jaxmps.make_params(2, dt=1e-3)
    with pytest.raises(ValueError, match="inflow"):
        jaxmps.simulate(case.scene, plain, case.state, 2, 2)


def test_tail_weir_holds_water_above_its_crest():
    """With a tail weir the downstream level rises above the crest and the water
    spills over it (the outflow plane lies behind the weir). The impact of the
    supercritical flow on the weir is violent: with fixed steps it needed Courant
    0.03-0.04 (0.2 explodes at ~0.4 s, 0.05 went non-finite at 0.55 s); with
    adaptive steps and the density term per reference step it runs at the default
    Courant 0.1 (float32 and float64, this weir and a 0.05 m one on a 0.45 m bed:
    no particle left the domain). The splash is chaotic (a 1e-10 m round-off
    difference grows to 0.1 m within 0.25 s); the bed runs on under the weir and a
    head-box wall reaches the domain top, so that no particle can leave below the
    weir or over the upstream end."""
    l0 = 0.0075
    case = jaxmps.scenes.flume(spacing=l0, bed_length=0.3, weir_height=0.06, t_end=0.8)
    tr = _run(case, 0.8)
    t = np.asarray(tr.saved["time"])
    level = np.asarray(tr.saved["level_downstream"])[t > 0.5].mean()
    assert level > case.config["weir_height"]
    count = np.asarray(tr.saved["fluid_count"])
    assert count[-1] > count[0]  # storage grows behind the weir
    assert tr.result == jaxmps.Result.successful


# --- The inflow boundary on its own (kinematics: what it spawns and withdraws) ---


def _kinematic_inflow(dim, axis, direction, params, t_end, dt, spacing=0.02):
    """Advance a lone inflow boundary (no fluid solve) from t = 0 to `t_end`; return
    the fluid count after each step and the boundary's cross-section area."""
    import jax
    import jax.numpy as jnp

    cross = np.zeros(dim)
    top = np.full(dim, 0.1)  # a 0.1 m (x 0.1 m) face of 5 (x 5) particles
    points, kinds, inflow = jaxmps.fluid.inflow_boundary(
        0.3, cross, top, spacing, axis=axis, direction=direction
    )
    lower, upper = np.full(dim, -0.5), np.full(dim, 1.0)
    scene = jaxmps.make_scene(
        points, spacing, (lower, upper), capacity=len(points) + 4000
    )
    state = jaxmps.make_state(scene, points, kinds)
    params = eqx.tree_at(
        lambda p: p.inflow,
        jaxmps.make_params(dim, dt=dt),
        params,
        is_leaf=lambda x: x is None,
    )
    width = 0.1 ** (dim - 2)  # per metre in 2-D

    def one(state, _):
        new, short = jaxmps.fluid.apply_inflow(
            scene.discretisation, inflow, params.inflow, scene.grid, params.dt, state
        )
        new = eqx.tree_at(lambda s: s.time, new, state.time + params.dt)
        fluid = jnp.sum(new.active & (new.kind == int(jaxmps.Kind.FLUID)))
        return new, (fluid, short)

    steps = round(t_end / dt)
    state, (count, short) = jax.jit(lambda s: jax.lax.scan(one, s, None, steps))(state)
    assert not bool(np.any(short))
    return state, np.asarray(count), width, inflow


@pytest.mark.parametrize(
    ("dim", "axis", "direction"), [(2, 0, 1), (3, 0, -1), (3, 1, 1)]
)
def test_prescribed_series_inflow_volume_matches_discharge(dim, axis, direction):
    """A tabulated velocity and depth (a long wave rising, holding and falling) fed
    through a boundary facing any way, in 2-D and 3-D: the volume that entered
    equals the integral of velocity x depth x width within 2 % (it is sampled at
    whole columns and rows of l0 = 2 cm)."""
    times = np.array([0.0, 0.3, 0.6, 1.0])
    velocity = np.array([0.2, 1.0, 1.0, 0.3])
    depth = np.array([0.03, 0.1, 0.1, 0.05])
    series = jaxmps.fluid.InflowParams(velocity=velocity, times=times, depth=depth)
    dt = 1e-3
    if axis == dim - 1:
        pytest.skip("the vertical axis has no depth")
    state, count, width, inflow = _kinematic_inflow(
        dim, axis, direction, series, 1.0, dt
    )
    t = np.linspace(0.0, 1.0, 20001)
    discharge = np.interp(t, times, velocity) * np.interp(t, times, depth) * width
    prescribed = np.trapezoid(discharge, t)
    entered = count[-1] * 0.02**dim
    assert entered == pytest.approx(prescribed, rel=0.02)
    # Spawned particles sit in front of the boundary (on its fluid side) only.
    fluid = np.asarray(state.active & (state.kind == int(jaxmps.Kind.FLUID)))
    ahead = direction * (np.asarray(state.position)[fluid, axis] - inflow.origin)
    assert np.all(ahead > 0)
    # Depth decides the rows: nothing spawned above the highest prescribed depth.
    assert np.asarray(state.position)[fluid, dim - 1].max() < depth.max()


def _tank_with_inflow(
    l0, depth, length, velocity, wall=0.16, series=None, absorbing=False, pool=100
):
    """A 2-D tank `length` long filled to `depth` whose left wall is an inflow
    boundary `wall` high (`absorbing` or not): scene, params, state, the fluid
    and the Inflow."""
    fluid = jaxmps.geometry.block([0.0, 0.0], [length, depth], l0)
    walls, wall_kind = jaxmps.geometry.tank([0.0, 0.0], [length, wall], l0)
    keep = ~((walls[:, 0] < 0) & (walls[:, 1] > 0))
    walls, wall_kind = walls[keep], wall_kind[keep]
    first = len(fluid) + len(walls)
    boundary, boundary_kind, inflow = jaxmps.fluid.inflow_boundary(
        0.0, [0.0, 0.0], [0.0, wall], l0, first=first, absorbing=absorbing
    )
    position = np.concatenate([fluid, walls, boundary])
    kind = np.concatenate(
        [np.full(len(fluid), int(jaxmps.Kind.FLUID)), wall_kind, boundary_kind]
    )
    scene = jaxmps.make_scene(
        position,
        l0,
        ([-0.1, -0.1], [length + 0.1, 0.3]),
        capacity=len(position) + pool,
    )
    scene = eqx.tree_at(lambda s: s.inflow, scene, inflow, is_leaf=lambda x: x is None)
    params = eqx.tree_at(
        lambda p: p.inflow,
        jaxmps.make_params(2, dt=1e-3),
        jaxmps.fluid.InflowParams(velocity=velocity, **(series or {})),
        is_leaf=lambda x: x is None,
    )
    state = jaxmps.make_state(scene, position, kind)
    return scene, params, state, fluid, inflow


def test_negative_inflow_velocity_withdraws_water_at_the_prescribed_rate():
    """Aida's outflow rule in a full run: a tank 0.4 m long, 0.1 m deep, whose left
    wall is an inflow boundary driven backwards at 0.1 m/s for 0.5 s. The water
    follows the boundary and the columns in front of it go back to the pool: what
    leaves is u x (the mean depth, which falls from 0.1 to about 0.089 m) x T, and
    no water is left behind or inside the boundary that stepped into it."""
    l0, depth, length = 0.01, 0.1, 0.4
    scene, params, state, fluid, inflow = _tank_with_inflow(l0, depth, length, -0.1)
    # 0.55 s: midway between the fifth and sixth withdrawal (one per l0 travelled).
    times = np.linspace(0.05, 0.55, 11)
    count = jaxmps.scenes.FluidCount("fluid")
    run = jaxmps.simulate(
        scene,
        params,
        state,
        times=times,
        observe=jaxmps.scenes.observe_probes((count,)),
    )
    left = np.asarray(run.saved["fluid"])
    removed = (len(fluid) - left[-1]) * l0**2
    final_depth = left[-1] * l0**2 / length
    prescribed = 0.1 * times[-1] * 0.5 * (depth + final_depth)
    # The rule acts in whole columns: within one column of u x mean depth x T.
    assert abs(removed - prescribed) <= depth * l0
    assert np.all(np.diff(left) <= 0)
    x = np.asarray(run.state.position)
    wet = np.asarray(run.state.active & (run.state.kind == int(jaxmps.Kind.FLUID)))
    face = x[list(inflow.pressure_layer), 0].max()
    assert x[wet, 0].min() > face + 0.4 * l0


@pytest.mark.parametrize("absorbing", [False, True])
def test_a_wave_reflected_back_to_an_absorbing_inflow_leaves_the_tank(absorbing):
    """A long wave 2 cm high on 10 cm of water (the simple wave's depth and
    velocity, for 0.4 s) runs 1 m to the tank's far wall and back. A piston
    boundary (not absorbing) stops and reflects it again: the wave's water
    stays in the tank. An absorbing boundary lets the reflection out
    (withdrawing water as it arrives): after it has passed, the tank holds its
    still water again, within a quarter of the wave's volume."""
    l0, depth, length, eta, g = 0.01, 0.1, 1.0, 0.02, 9.81
    u = 2 * (np.sqrt(g * (depth + eta)) - np.sqrt(g * depth))
    series = dict(
        times=np.array([0.0, 0.1, 0.4, 0.5]),
        depth=np.array([depth, depth + eta, depth + eta, depth]),
    )
    scene, params, state, fluid, _ = _tank_with_inflow(
        l0,
        depth,
        length,
        np.array([0.0, u, u, 0.0]),
        wall=0.2,
        series=series,
        absorbing=absorbing,
        pool=300,
    )
    # The reflection is back at the boundary at about 2 s, out by 2.6 s.
    times = np.array([0.5, 1.0, 3.0])
    count = jaxmps.scenes.FluidCount("fluid")
    run = jaxmps.simulate(
        scene,
        params,
        state,
        times=times,
        observe=jaxmps.scenes.observe_probes((count,)),
    )
    n = np.asarray(run.saved["fluid"])
    wave = n[1] - len(fluid)  # what the wave brought in
    t = np.linspace(0.0, 0.5, 5001)
    brought = np.trapezoid(
        np.interp(t, series["times"], [0.0, u, u, 0.0])
        * np.interp(t, series["times"], series["depth"]),
        t,
    )
    assert wave * l0**2 == pytest.approx(brought, rel=0.15)
    if absorbing:
        assert abs(n[-1] - len(fluid)) < 0.25 * wave
    else:
        assert n[-1] - len(fluid) > 0.9 * wave


@pytest.mark.parametrize("absorbing", [False, True])
def test_an_absorbing_inflow_feeds_a_rising_wave_as_prescribed(absorbing):
    """A long wave rising 6 cm over 1 s on 10 cm of water, in a tank long
    enough that nothing comes back within 1.6 s: the volume fed (the particles
    spawned plus the column the boundary has pushed since its last spawn)
    follows the series' integral of u d within 0.4 of a column, for the piston
    and for the absorbing boundary alike (an absorber comparing the depth in
    front with the depth fed now, not with what it fed into those columns,
    fed 1.4 columns too many here while the wave rose)."""
    l0, depth, length, eta, g = 0.02, 0.1, 2.5, 0.06, 9.81
    times = np.array([0.0, 1.0, 3.0])
    d = np.array([depth, depth + eta, depth + eta])
    u = 2 * (np.sqrt(g * d) - np.sqrt(g * depth))
    scene, params, state, fluid, inflow = _tank_with_inflow(
        l0,
        depth,
        length,
        u,
        wall=0.3,
        series=dict(times=times, depth=d),
        absorbing=absorbing,
        pool=1500,
    )
    face = inflow.pressure_layer[0]

    def observe(scene, state):
        fluid_now = jnp.sum(state.active & (state.kind == int(jaxmps.Kind.FLUID)))
        return {"fluid": fluid_now, "travel": state.position[face, 0] - inflow.origin}

    at = np.array([1.2, 1.4, 1.6])
    run = jaxmps.simulate(scene, params, state, times=at, observe=observe)
    column = (depth + eta) * l0
    fed = (np.asarray(run.saved["fluid"]) - len(fluid)) * l0**2
    fed = fed + np.asarray(run.saved["travel"]) * (depth + eta)
    t = np.linspace(0.0, at[-1], 16001)
    flux = np.interp(t, times, u) * np.interp(t, times, d)
    series = [np.trapezoid(flux[t <= a], t[t <= a]) for a in at]
    assert np.all(np.abs(fed - series) < 0.4 * column)


def test_inflow_params_refuse_bad_series():
    with pytest.raises(ValueError, match="increasing"):
        jaxmps.fluid.InflowParams(velocity=[1.0, 1.0], times=[0.0, 0.0])
    with pytest.raises(ValueError, match="shape"):
        jaxmps.fluid.InflowParams(velocity=[1.0, 1.0, 2.0], times=[0.0, 1.0])
    with pytest.raises(ValueError, match="depth"):
        jaxmps.fluid.InflowParams(velocity=1.0, depth=-0.1)


def test_inflow_deeper_than_its_boundary_is_refused():
    """A wave higher than the inflow boundary (0.16 m) cannot be fed: refused
    before the run, naming the setting."""
    scene, params, state, _, _ = _tank_with_inflow(
        0.02, 0.1, 0.4, [1.0, 1.0], series={"times": [0.0, 1.0], "depth": [0.1, 0.2]}
    )
    with pytest.raises(ValueError, match="inflow.depth"):
        jaxmps.simulate(scene, params, state, 2, 2)
