"""Adaptive time steps (`jaxmps.Adaptive`), saves at exact times, and the bounds
of a save's while loop: the dt against the limits computed by hand, steps taken
again, the failures (dt below its minimum, too many steps), gradients against
finite differences, and batches whose members take different step counts."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import Kind, Result


def _hydrostatic(**settings):
    return jaxmps.scenes.hydrostatic(spacing=0.02, width=0.1, depth=0.1, **settings)


def _kicked(case, speed: float):
    """The case's state with its first fluid particle moving at `speed` along x."""
    i = int(np.nonzero(np.asarray(case.state.kind) == int(Kind.FLUID))[0][0])
    velocity = case.state.velocity.at[i, 0].set(speed)
    return eqx.tree_at(lambda s: s.velocity, case.state, velocity)


def _with(scene, stepping):
    return eqx.tree_at(
        lambda s: s.time_step, scene, stepping, is_leaf=lambda x: x is None
    )


def test_scenes_step_adaptively_by_default_and_fixed_on_request():
    for name, defaults in jaxmps.scenes.available().items():
        assert defaults["dt"] == "adaptive", name
    case = _hydrostatic()
    assert isinstance(case.scene.time_step, jaxmps.Adaptive)
    # The largest step is the Courant rule of the scene's velocity scale.
    speed = math.sqrt(2 * 9.81 * 0.1)
    assert float(case.params.dt) == pytest.approx(0.2 * 0.02 / speed)
    fixed = _hydrostatic(dt=1e-3)
    assert fixed.scene.time_step is None and float(fixed.params.dt) == 1e-3
    bounded = _hydrostatic(dt_max=2e-3, dt_min=1e-5)
    assert float(bounded.params.dt) == 2e-3
    assert bounded.scene.time_step.dt_min == 1e-5


@pytest.mark.parametrize(
    "settings, courant",
    [
        ({}, 0.1),
        ({"scheme": "standard_ds"}, 0.2),
        ({"scheme": "high_accuracy"}, 0.2),
        ({"solver": "explicit"}, 0.1),
        ({"scheme": "standard_ds", "courant": 0.15}, 0.15),
        ({"solver": "explicit", "courant": 0.05}, 0.05),
    ],
)
def test_the_default_courant_number_follows_the_scheme(settings, courant):
    """Courant 0.2 where dynamic stabilisation separates the particles at their
    predicted positions, 0.1 otherwise; a `courant` setting wins over both."""
    case = _hydrostatic(**settings)
    assert case.scene.time_step.courant_for(case.scene) == courant
    state = _kicked(case, 3.0)
    limits = jaxmps.time_step_limits(case.scene, case.params, state)
    assert float(limits["courant"]) == pytest.approx(courant * 0.02 / 3.0)


@pytest.mark.parametrize("courant", [0.0, 1.5, -0.1, float("nan")])
def test_a_courant_number_outside_the_unit_interval_is_refused(courant):
    with pytest.raises(ValueError, match="Adaptive.courant must be in"):
        jaxmps.Adaptive(courant=courant)


@pytest.mark.slow
def test_stabilised_schemes_keep_the_surge_front_at_their_longer_default_step():
    """`standard_ds` at its default Courant 0.2 on Koshizuka & Oka's column: every
    step accepted, the surge front within 2 % of the same run at Courant 0.1 at T =
    1-2.5 (measured at l0 = 7.3 mm to 1 s: within 1 %), in fewer steps."""
    a = 0.146
    times = 0.00625 * np.arange(1, 41)  # to 0.25 s, T = 2.9
    fronts, steps = {}, {}
    for courant in (None, 0.1):
        settings = {} if courant is None else {"courant": courant}
        case = jaxmps.scenes.dam_break(spacing=0.0073, scheme="standard_ds", **settings)
        obs = jaxmps.scenes.observe_probes(case.probes)
        tr = jaxmps.simulate(
            case.scene, case.params, case.state, times=times, observe=obs
        )
        assert tr.result == Result.successful
        assert int(np.sum(np.asarray(tr.steps.rejected))) == 0, courant
        t = np.asarray(tr.saved["time"]) * math.sqrt(2 * 9.81 / a)
        fronts[courant] = np.interp([1.0, 1.5, 2.0, 2.5], t, tr.saved["front"]) / a
        steps[courant] = int(tr.state.step)
    np.testing.assert_allclose(fronts[None], fronts[0.1], rtol=0.02)
    assert steps[None] < 0.8 * steps[0.1], steps


@pytest.mark.parametrize(
    "settings, match",
    [
        ({"dt": "auto"}, "'adaptive' or a number of seconds"),
        ({"dt": 1e-3, "dt_max": 2e-3}, "dt_max bound adaptive steps"),
        ({"dt_min": 1.0}, "dt_min=1 s must be below the largest step"),
        ({"dt_max": -1.0}, "dt_max must be positive"),
    ],
)
def test_step_settings_are_checked(settings, match):
    with pytest.raises(ValueError, match=match):
        _hydrostatic(**settings)


def test_the_step_is_the_smallest_limit():
    case = _hydrostatic(viscosity=1e-6)
    l0, dt_max = 0.02, float(case.params.dt)
    speed = 3.0
    state = _kicked(case, speed)
    limits = jaxmps.time_step_limits(case.scene, case.params, state)
    assert float(limits["courant"]) == pytest.approx(0.1 * l0 / speed)
    assert float(limits["dt_max"]) == dt_max
    assert not np.isfinite(float(limits["force"]))  # no step taken yet
    lam = case.scene.lam
    assert float(limits["viscous"]) == pytest.approx(0.5 * 1.0 * lam / (4 * 1e-6))
    dt = float(jaxmps.time_step(case.scene, case.params, state))
    assert dt == pytest.approx(min(0.1 * l0 / speed, dt_max))
    # A step records its dt and its largest acceleration by forces (here gravity:
    # the semi-implicit pressure is a projection, not a force); the next step's
    # force limit reads it.
    new, _ = jaxmps.step(case.scene, case.params, state)
    assert float(new.dt) == pytest.approx(dt)
    assert float(new.acceleration) == pytest.approx(9.81, rel=1e-3)
    after = jaxmps.time_step_limits(case.scene, case.params, new)
    expected = 0.25 * math.sqrt(l0 / float(new.acceleration))
    assert float(after["force"]) == pytest.approx(expected)


def test_the_explicit_solver_adds_its_sound_limit():
    case = _hydrostatic(solver="explicit", sound_speed=20.0)
    limits = jaxmps.time_step_limits(case.scene, case.params, case.state)
    assert float(limits["solver"]) == pytest.approx(0.5 * 0.8 * 0.02 / 20.0)
    # Its pressure is a force: the force limit reads the whole acceleration.
    new, _ = jaxmps.step(case.scene, case.params, case.state)
    fluid = np.asarray(case.state.kind) == int(Kind.FLUID)
    change = np.linalg.norm(np.asarray(new.velocity - case.state.velocity), axis=-1)
    expected = change[fluid].max() / float(new.dt)
    assert float(new.acceleration) == pytest.approx(expected, rel=1e-6)
    # A largest step beyond the sound limit is not refused: each step is bounded.
    big = _hydrostatic(solver="explicit", sound_speed=20.0, dt_max=0.01)
    tr = jaxmps.simulate(big.scene, big.params, big.state, times=[0.01], throw=False)
    assert tr.result == Result.successful
    assert float(tr.steps.dt_max[0]) <= 0.4 * 0.02 / 20.0 * (1 + 1e-9)
    fixed = _hydrostatic(solver="explicit", sound_speed=20.0, dt=0.01)
    with pytest.raises(ValueError, match="stability limit"):
        jaxmps.simulate(fixed.scene, fixed.params, fixed.state, 1)


@pytest.mark.parametrize("fixed", [False, True])
def test_saves_land_on_the_requested_times(fixed):
    case = _hydrostatic(**({"dt": 0.004} if fixed else {}))
    times = np.array([0.013, 0.05, 0.0505, 0.07])
    tr = jaxmps.simulate(case.scene, case.params, case.state, times=times)
    dtype = np.asarray(tr.saved.time).dtype
    assert np.array_equal(np.asarray(tr.saved.time), times.astype(dtype))
    assert np.asarray(tr.state.time) == dtype.type(0.07)
    if fixed:
        # ceil(interval / dt) steps per save, the last two evened out.
        intervals = np.diff(np.concatenate([[0.0], times]))
        assert np.asarray(tr.steps.accepted).tolist() == [
            math.ceil(i / 0.004 - 1e-6) for i in intervals
        ]
        assert np.all(np.asarray(tr.steps.dt_max) <= 0.004 * (1 + 1e-6))
    assert int(tr.state.step) == int(np.sum(tr.steps.accepted))


def test_a_step_beyond_a_limit_is_taken_again():
    # Courant 1 a priori is twice the accepted 0.5: the step is taken again with
    # half the dt (or less) until it passes.
    case = _hydrostatic()
    scene = _with(case.scene, jaxmps.Adaptive(courant=1.0))
    state = _kicked(case, 20.0)  # a Courant limit of l0 / 20 = 1e-3 s < dt_max
    tr = jaxmps.simulate(scene, case.params, state, times=[0.002], throw=False)
    assert tr.result == Result.successful
    assert int(tr.steps.rejected[0]) >= 1
    assert float(tr.steps.dt_min[0]) <= 0.5 * 0.02 / 20.0
    # Without the retry the same first step is refused.
    first, _ = jaxmps.step(scene, case.params, state)
    assert first.result == Result.step_too_large


def test_a_step_below_dt_min_ends_the_run_with_the_state_before_it():
    case = _hydrostatic(dt_min=1e-3)
    state = _kicked(case, 50.0)  # Courant limit 0.1 l0 / 50 = 4e-5 s
    tr = jaxmps.simulate(case.scene, case.params, state, times=[0.02], throw=False)
    assert tr.result == Result.time_step_below_minimum
    assert float(tr.state.time) == 0.0 and int(tr.state.step) == 0
    with pytest.raises(Exception, match="dt_min"):
        jaxmps.simulate(case.scene, case.params, state, times=[0.02])


def test_a_save_needing_more_steps_than_the_bound_is_reported():
    case = _hydrostatic()
    tr = jaxmps.simulate(
        case.scene, case.params, case.state, times=[0.1], max_steps=3, throw=False
    )
    assert tr.result == Result.too_many_steps
    assert int(tr.state.step) == 3 and float(tr.state.time) < 0.1
    assert "max_steps" in Result[tr.result]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"times": [0.02, 0.01]}, "times must increase"),
        ({"times": [0.0]}, "must come after the state's time"),
        ({"times": np.array([[0.1]])}, "1-D array"),
        ({"times": [0.1], "n_steps": 4}, "either `times`"),
        ({}, "needs `n_steps`"),
        ({"n_steps": 4, "max_steps": 2}, "at least save_every"),
    ],
)
def test_loop_arguments_are_checked(kwargs, match):
    case = _hydrostatic()
    with pytest.raises(ValueError, match=match):
        jaxmps.simulate(case.scene, case.params, case.state, **kwargs)


def _moving(dt_max: float, **settings):
    """A small dam break whose steps the Courant limit sets once it moves."""
    return jaxmps.scenes.dam_break(
        spacing=0.02,
        column_width=0.1,
        column_height=0.2,
        tank_length=0.4,
        tank_height=0.3,
        dt_max=dt_max,
        **settings,
    )


def _mean_x(state):
    fluid = state.kind == int(Kind.FLUID)
    return jnp.sum(jnp.where(fluid, state.position[:, 0], 0.0)) / jnp.sum(fluid)


def _gravity(params, g):
    return eqx.tree_at(lambda p: p.gravity, params, jnp.stack([0.0 * g, -g]))


def _observe_dt(scene, state):
    del scene
    return state.dt


@pytest.mark.slow
def test_gradient_of_an_adaptive_rollout_matches_finite_differences():
    assert jax.config.jax_enable_x64  # tests/conftest.py
    # Finite differences of solves need converged solves (the default tolerance
    # leaves a residual that varies with g from one CG iteration count to the next).
    case = _moving(dt_max=0.01, rtol=1e-13, max_iterations=5000)
    n = 14

    def adaptive(g):
        tr = jaxmps.simulate(
            case.scene,
            _gravity(case.params, g),
            case.state,
            n,
            1,
            _observe_dt,
            throw=False,
        )
        return _mean_x(tr.state), tr.saved

    (value, dts), grad = jax.value_and_grad(adaptive, has_aux=True)(9.81)
    dts = np.asarray(dts)
    # The Courant limit took over from dt_max: the steps differ.
    assert dts.max() / dts.min() > 1.5

    fixed = _with(case.scene, None)

    def scheduled(g):
        params = _gravity(case.params, g)

        def one(state, dt):
            return jaxmps.step(fixed, params, state, dt=dt)[0], None

        state = jaxmps.with_neighbour_lists(fixed, case.state)
        state, _ = jax.lax.scan(one, state, jnp.asarray(dts))
        return _mean_x(state)

    # The dt is a constant to the gradient: the gradient is that of the same
    # steps taken with those dt values (params.dt, dt_max, the reference step
    # of the density relaxation), which finite differences check.
    assert float(scheduled(9.81)) == pytest.approx(float(value), rel=1e-12)
    h = 1e-4
    fd = (scheduled(9.81 + h) - scheduled(9.81 - h)) / (2 * h)
    assert float(grad) == pytest.approx(float(fd), rel=1e-4)


def test_batch_members_take_their_own_number_of_steps():
    case = _moving(dt_max=0.01)
    gravities = jnp.asarray([4.0, 9.81, 20.0])
    times = jnp.asarray([0.02, 0.04])

    def one(g):
        tr = jaxmps.simulate(
            case.scene, _gravity(case.params, g), case.state, times=times, throw=False
        )
        return tr.state.position, tr.steps.accepted, tr.result

    positions, accepted, results = jax.vmap(one)(gravities)
    counts = np.asarray(accepted).sum(axis=1)
    assert len(set(counts.tolist())) > 1  # stronger gravity, faster flow, more steps
    for k, g in enumerate(gravities):
        alone, steps, result = one(g)
        assert result == Result.successful
        assert np.asarray(steps).tolist() == np.asarray(accepted[k]).tolist()
        np.testing.assert_allclose(positions[k], alone, rtol=0, atol=1e-5)


def test_run_saves_at_exact_times_with_the_steps_behind_each_frame(tmp_path):
    case = _hydrostatic()
    out = tmp_path / "run.h5"
    jaxmps.run(case, t_end=0.05, save_every=0.02, out=out, progress=False)
    data = jaxmps.io.read_run(out)
    dtype = data.frames["time"].dtype
    assert np.array_equal(data.frames["time"], np.array([0, 0.02, 0.04, 0.05], dtype))
    assert np.isnan(data.frames["dt_min"][0]) and np.isnan(data.frames["dt_max"][0])
    assert np.all(data.frames["dt_max"][1:] <= float(case.params.dt) * (1 + 1e-6))
    assert np.all(data.frames["rejected"] == 0)
    jaxmps.run(case, t_end=0.09, save_every=0.02, out=out, restart=True, progress=False)
    data = jaxmps.io.read_run(out)
    assert np.allclose(
        data.frames["time"], [0.0, 0.02, 0.04, 0.05, 0.06, 0.08, 0.09], atol=1e-7
    )
    assert len(data.frames["dt_min"]) == 7
    assert float(data.state["dt"]) > 0
