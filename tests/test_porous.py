"""Porous damping regions: the resistance -u/kappa - c|u|u in boxes of the fluid
(seed 001 eq. 5.1), its exact update, the box and direction it acts on, the
frame of a shaken tank, still water, its gradient, and what bad input gets."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_pipeline import _scopes

import jaxmps
from jaxmps import PorousRegion, fluid, scenes
from jaxmps.geometry import block


def _free_block(velocity, l0=0.01, solver=None):
    """A 10 x 10 water block in free flight (no walls, no gravity) moving at a
    uniform `velocity`: (scene, params, state)."""
    position = block([0.0, 0.0], [0.1, 0.1], l0)
    kind = np.zeros(len(position), np.int32)
    lower, upper = np.array([-0.5, -0.5]), np.array([0.6, 0.6])
    scheme = jaxmps.schemes.explicit() if solver == "explicit" else None
    scene = jaxmps.make_scene(position, l0, (lower, upper), scheme=scheme)
    params = jaxmps.make_params(2, dt=1e-3, gravity=0.0, viscosity=0.0)
    velocity = np.broadcast_to(np.asarray(velocity, float), position.shape)
    state = jaxmps.make_state(scene, position, kind, velocity=velocity)
    return scene, params, state


def test_resistance_solves_the_backward_euler_step():
    """u_new (1 + dt/kappa) + dt c |u_new| u_new = u for the factor the update
    applies, with c = 0 the linear 1/(1 + dt/kappa); the factor lies in (0, 1]."""
    speed = jnp.asarray([0.0, 1e-6, 0.3, 2.0, 50.0])
    dt = 1e-3
    for kappa, drag in [(0.01, 0.0), (0.01, 40.0), (1e9, 40.0), (2.0, 0.5)]:
        factor = fluid.resistance_factor(
            speed, *(jnp.asarray(v) for v in (dt, kappa, drag))
        )
        new = speed * factor
        residual = new * (1 + dt / kappa) + dt * drag * new**2 - speed
        assert np.all(np.abs(residual) <= 1e-14 * (1 + speed))
        assert np.all((factor > 0) & (factor <= 1))
    linear = fluid.resistance_factor(speed, *(jnp.asarray(v) for v in (dt, 0.01, 0.0)))
    np.testing.assert_allclose(linear, 1 / (1 + dt / 0.01), rtol=1e-15)


def test_uniform_flow_decays_geometrically_along_the_damped_axis_only():
    """A free water block at uniform velocity inside a region: the damped component
    falls as (1 + dt/kappa)^-n (exact: a uniform velocity has no pressure), the
    other is untouched; with 'all' both fall; outside the box nothing changes."""
    u0 = (0.2, -0.1)
    n, dt, kappa = 20, 1e-3, 0.01
    decay = (1 + dt / kappa) ** -n
    for direction, expected in [
        ("x", (u0[0] * decay, u0[1])),
        ("vertical", (u0[0], u0[1] * decay)),
        ("all", (u0[0] * decay, u0[1] * decay)),
    ]:
        scene, params, state = _free_block(u0)
        region = PorousRegion(((-1, -1), (2, 2)), kappa, direction)
        scene, params = jaxmps.add_porous_regions(scene, params, state, [region])
        out = jaxmps.simulate(scene, params, state, n_steps=n).state
        np.testing.assert_allclose(
            np.asarray(out.velocity)[np.asarray(out.active)],
            np.broadcast_to(expected, (100, 2)),
            rtol=1e-9,
            atol=1e-12,
        )
    # Half the block inside (x < 0.045): only those particles slow, by the factor
    # of one step.
    scene, params, state = _free_block(u0)
    region = PorousRegion(((-1, -1), (0.045, 2)), kappa, "all")
    scene, params = jaxmps.add_porous_regions(scene, params, state, [region])
    out, _ = jaxmps.step(scene, params, state)
    inside = np.asarray(state.position)[:, 0] < 0.045
    speed = np.linalg.norm(np.asarray(out.velocity), axis=1)
    np.testing.assert_allclose(speed[inside], np.hypot(*u0) / (1 + dt / kappa))
    np.testing.assert_allclose(speed[~inside], np.hypot(*u0), rtol=1e-6)


def test_quadratic_drag_follows_its_ode():
    """The quadratic drag alone (kappa -> inf): du/dt = -c u^2 has
    u = u0 / (1 + c u0 t); the backward steps follow it to first order in dt."""
    u0, c, n, dt = 0.5, 20.0, 100, 1e-3
    scene, params, state = _free_block((u0, 0.0))
    region = PorousRegion(((-1, -1), (2, 2)), 1e9, "x", drag=c)
    scene, params = jaxmps.add_porous_regions(scene, params, state, [region])
    out = jaxmps.simulate(scene, params, state, n_steps=n).state
    u = np.asarray(out.velocity)[np.asarray(out.active), 0]
    exact = u0 / (1 + c * u0 * n * dt)
    assert abs(u.mean() / exact - 1) < 2 * c * u0 * dt  # first order
    np.testing.assert_allclose(u, u.mean(), rtol=1e-9)


def test_still_water_in_a_region_keeps_its_hydrostatic_pressure():
    """Water settling in a tank wholly inside a region (kappa = 0.01 s, dt/kappa =
    0.1): the resistance acts on velocity, not on the gravity the pressure
    balances, so the pressure field is that of the tank without a region within
    0.5 % in the mean (damping the velocity after gravity would hold it 9 % short,
    by 1/(1 + dt/kappa)), and the water moves less."""
    kwargs = dict(spacing=0.02, width=0.2, depth=0.2, dt=1e-3)
    plain = scenes.hydrostatic(**kwargs)
    damped = scenes.hydrostatic(
        **kwargs, porous_kappa=0.01, porous_box="-1,-1,1,1", porous_direction="all"
    )
    ends = [
        jaxmps.simulate(c.scene, c.params, c.state, n_steps=50).state
        for c in (plain, damped)
    ]
    water = np.asarray(damped.state.kind) == int(jaxmps.Kind.FLUID)
    pressure = [np.asarray(end.pressure)[water] for end in ends]
    assert abs(pressure[1].sum() / pressure[0].sum() - 1) < 0.005
    speed = [np.abs(np.asarray(end.velocity)[water]).max() for end in ends]
    assert speed[1] < speed[0]


def test_region_moves_with_a_shaken_tank():
    """In a shaken tank the region is fixed to the walls: the scene marks it
    moving, its box shifts with the walls' displacement and it damps the velocity
    relative to the walls (water moving with the tank is not slowed)."""
    case = scenes.sloshing_tank(
        spacing=0.025,
        settle=0.0,
        porous_kappa=0.01,
        porous_box="-1,-1,2,2",
        porous_direction="all",
    )
    assert case.scene.porous.moving
    # Water that moves with the walls: give every fluid particle the walls'
    # velocity of the first step; the region leaves it as it is.
    params, state = case.params, case.state
    motion = case.scene.motion
    dt = params.dt
    wall_speed = motion.law.displacement(params.motion, dt) / dt
    moving = state.velocity.at[:, 0].set(wall_speed)
    state = jaxmps.make_state(
        case.scene,
        np.asarray(state.position)[np.asarray(state.active)],
        np.asarray(state.kind)[np.asarray(state.active)],
        velocity=np.asarray(moving)[np.asarray(state.active)],
    )
    damped = jaxmps._step._porous(case.scene, params, state)
    np.testing.assert_allclose(damped, state.velocity, atol=1e-15)
    # A fixed region (a wave tank's piston moves alone) does not move.
    wave = scenes.wave_tank(
        spacing=0.04, porous_kappa=0.1, porous_box="1,-1,2,2", porous_direction="x"
    )
    assert not wave.scene.porous.moving


def test_region_damps_sloshing_and_compiles_only_where_present():
    """A region under the surface at the wall of a shaken tank (resonant forcing,
    3 s) lowers the sloshing mode (the smaller kappa, the lower), and a scene
    without one has no `porous` stage in its step program."""
    kwargs = dict(spacing=0.025, settle=0.0, dt=2e-3, amplitude=5e-3)
    plain = scenes.sloshing_tank(**kwargs)
    assert "porous" not in _scopes(plain.scene, plain.params, plain.state)
    peaks = []
    for kappa in (None, 0.2, 0.02):
        extra = (
            {}
            if kappa is None
            else dict(porous_kappa=kappa, porous_box="0,0.15,0.2,0.3")
        )
        case = scenes.sloshing_tank(**kwargs, **extra)
        if kappa is not None:
            assert "porous" in _scopes(case.scene, case.params, case.state)
        traj = jaxmps.simulate(
            case.scene,
            case.params,
            case.state,
            n_steps=1500,
            save_every=10,
            observe=scenes.observe_probes(case.probes),
        )
        assert traj.result == jaxmps.Result.successful
        peaks.append(float(np.max(np.abs(traj.saved["mode1"]))))
    # measured: 0.054, 0.031, 0.0073 m
    assert peaks[0] > 1.5 * peaks[1] > 1.5 * 2 * peaks[2]


@pytest.mark.slow
def test_kappa_gradient_matches_finite_differences():
    """d(probe)/d kappa of a short rollout of a shaken tank with a region, by
    reverse mode against central differences (float64), in the seed's regime
    (kappa = 0.01 s, far below the forcing period) and a softer one."""
    case = scenes.sloshing_tank(
        spacing=0.05,
        settle=0.0,
        dt=2e-3,
        amplitude=0.01,
        porous_kappa=0.05,
        porous_box="0,0.1,0.25,0.35",
    )
    observe = scenes.observe_probes(case.probes)

    def loss(log_kappa):
        kappa = jnp.exp(log_kappa)[None]
        params = eqx.tree_at(lambda p: p.porous.kappa, case.params, kappa)
        traj = jaxmps.simulate(
            case.scene, params, case.state, n_steps=40, save_every=10, observe=observe
        )
        return jnp.sum(traj.saved["mode1"] ** 2)

    for kappa in (0.01, 0.2):
        x = jnp.log(kappa)
        grad = jax.grad(loss)(x)
        h = 1e-4
        fd = (loss(x + h) - loss(x - h)) / (2 * h)
        assert abs(float(grad) - float(fd)) <= 1e-4 * abs(float(fd)) + 1e-14
        assert abs(float(fd)) > 0


@pytest.mark.parametrize(
    "settings, message",
    [
        (dict(porous_kappa=0.0, porous_box="0,0,0.2,0.2"), "porous_kappa must be"),
        (dict(porous_kappa=-1.0, porous_box="0,0,0.2,0.2"), "porous_kappa must be"),
        (
            dict(porous_kappa=float("nan"), porous_box="0,0,0.2,0.2"),
            "porous_kappa must be",
        ),
        (dict(porous_kappa=0.1, porous_box="5,5,6,6"), "entirely outside the domain"),
        (dict(porous_kappa=0.1, porous_box="0,0.3,0.2,0.4"), "holds no fluid"),
        (dict(porous_kappa=0.1, porous_box="0.2,0,0.1,0.2"), "below the upper"),
        (dict(porous_kappa=0.1, porous_box="0,0,0.2"), "porous_box"),
        (dict(porous_kappa=0.1, porous_box="0,0,a,0.2"), "porous_box"),
        (dict(porous_kappa=0.1), "porous_box is missing"),
        (dict(porous_box="0,0,0.2,0.2"), "porous_kappa is missing"),
        (
            dict(porous_kappa=0.1, porous_box="0,0,0.2,0.2", porous_direction="z"),
            "porous_direction='z'",
        ),
        (
            dict(porous_kappa=0.1, porous_box="0,0,0.2,0.2", porous_direction="up"),
            "porous_direction='up'",
        ),
        (
            dict(porous_kappa=0.1, porous_box="0,0,0.2,0.2", porous_drag=-1.0),
            "porous_drag must be",
        ),
        (dict(porous_drag=1.0), "need a region"),
    ],
)
def test_bad_regions_are_refused_naming_the_setting(settings, message):
    with pytest.raises(ValueError, match=message):
        scenes.hydrostatic(spacing=0.05, width=0.2, depth=0.2, **settings)


def test_several_regions_and_run_file_config():
    """Several regions from a list (PorousRegion or dicts) and one from the
    settings; the config records them so that the scene rebuilds the same."""
    listed = [
        PorousRegion(((0, 0), (0.1, 0.1)), 0.05, "x"),
        dict(box=[[0.1, 0], [0.2, 0.1]], kappa=0.2, direction="all", drag=3.0),
    ]
    case = scenes.hydrostatic(
        spacing=0.05,
        width=0.2,
        depth=0.2,
        porous_kappa=0.01,
        porous_box="0,0.1,0.2,0.2",
        porous_regions=listed,
    )
    assert case.scene.porous.count == 3
    assert case.scene.porous.axes == (1, 0, None)
    np.testing.assert_allclose(case.params.porous.kappa, [0.01, 0.05, 0.2])
    np.testing.assert_allclose(case.params.porous.drag, [0.0, 0.0, 3.0])
    again = scenes.build(
        "hydrostatic",
        **{
            k: v
            for k, v in case.config.items()
            if k in scenes.available()["hydrostatic"]
        },
    )
    assert again.scene.porous == case.scene.porous
    np.testing.assert_array_equal(again.params.porous.kappa, case.params.porous.kappa)


def test_dam_break_wet_bed_lies_on_the_column_lattice_and_bad_depths_are_refused():
    """`bed_depth`: still water over the floor beside the column (the porous-dam
    experiment of calibration/porous_dam_liu1999.py stands on one), on the
    column's lattice; a depth that is negative, not finite or not below the
    column gets an error naming the setting."""
    settings = dict(spacing=0.01, column_width=0.1, column_height=0.2)
    dry = jaxmps.scenes.dam_break(**settings)
    wet = jaxmps.scenes.dam_break(**settings, bed_depth=0.03)
    fluid = np.asarray(wet.state.kind) == int(jaxmps.Kind.FLUID)
    position = np.asarray(wet.state.position)[fluid]
    n_dry = int((np.asarray(dry.state.kind) == int(jaxmps.Kind.FLUID)).sum())
    length = wet.config["tank_length"]
    bed = position[position[:, 0] > 0.1]
    assert len(position) == n_dry + len(bed)
    assert len(bed) == round((length - 0.1) / 0.01) * 3
    assert bed[:, 1].max() == pytest.approx(0.025)
    # One lattice: every x and y a half-integer number of spacings.
    cells = position / 0.01 - 0.5
    assert np.allclose(cells, np.round(cells), atol=1e-9)
    assert wet.config["bed_depth"] == pytest.approx(0.03)
    assert dry.config["bed_depth"] == 0.0
    for bad in (-0.01, 0.2, float("inf")):
        with pytest.raises(ValueError, match="bed_depth"):
            jaxmps.scenes.dam_break(**settings, bed_depth=bad)
