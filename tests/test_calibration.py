"""`jaxmps.sweep` and `jaxmps.calibrate`."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import jaxmps
from jaxmps.calibration import Bounded, Curve, Log, calibrate, curve_loss
from jaxmps.calibration._fields import set_field


@pytest.fixture(scope="module")
def case():
    return jaxmps.scenes.dam_break(spacing=0.0146)


def test_sweep_equals_single_runs_and_chunks(case):
    nus = jnp.array([1e-6, 1e-2, 3e-2])
    res = jaxmps.sweep(case, {"viscosity": nus}, n_steps=40, save_every=20, chunk=2)
    assert res.saved["front"].shape == (3, 2)
    assert np.all(np.asarray(res.result) == 0)
    obs = jaxmps.scenes.observe_probes(case.probes)
    for i, nu in enumerate(nus):
        p = set_field(case.params, "viscosity", nu)
        tr = jaxmps.simulate(case.scene, p, case.state, 40, 20, obs)
        np.testing.assert_allclose(res.saved["front"][i], tr.saved["front"], rtol=1e-10)
    # Viscosity slows the front: the sweep sees the physics.
    front = np.asarray(res.saved["front"])[:, -1]
    assert front[0] > front[1] > front[2]


def test_sweep_rejects_bad_input(case):
    with pytest.raises(ValueError, match="Valid fields"):
        jaxmps.sweep(case, {"viscosty": jnp.array([1.0])}, n_steps=2)
    with pytest.raises(ValueError, match="same length"):
        jaxmps.sweep(case, {"viscosity": jnp.ones(2), "beta": jnp.ones(3)}, n_steps=2)


def test_curve_loss_interpolates_and_windows():
    curve = Curve(
        times=np.array([0.0, 1.0, 2.0]),
        values=np.array([0.0, 1.0, 0.0]),
        window=(0.5, 2.0),
    )
    sim_t = jnp.linspace(0.0, 2.0, 21)
    sim = jnp.where(sim_t <= 1.0, sim_t, 2.0 - sim_t) + 0.1
    assert float(curve_loss(sim_t, sim, curve)) == pytest.approx(0.01, rel=1e-9)
    with pytest.raises(ValueError, match="increasing"):
        Curve(times=np.array([0.0, 0.0]), values=np.array([1.0, 2.0]))


def test_transforms_round_trip():
    for t, x in [(Log(), 0.3), (Bounded(0.1, 0.9), 0.45)]:
        assert float(t.forward(t.inverse(jnp.asarray(x)))) == pytest.approx(x)
    assert float(Bounded(0.1, 0.9).forward(jnp.asarray(50.0))) <= 0.9


@pytest.mark.slow
def test_calibrate_recovers_viscosity_from_synthetic_front(case, tmp_path):
    """Synthetic front curve made with nu = 0.01; start from 0.006; recovered within
    2 % in at most 25 Adam iterations (log scale)."""
    obs = jaxmps.scenes.observe_probes(case.probes)
    truth = set_field(case.params, "viscosity", jnp.asarray(0.01))
    tr = jaxmps.simulate(case.scene, truth, case.state, 100, 5, obs)
    curve = Curve(
        times=np.asarray(tr.saved["time"]), values=np.asarray(tr.saved["front"])
    )
    res = calibrate(
        case,
        {"viscosity": Log()},
        curve,
        "front",
        100,
        5,
        optimiser=optax.adam(0.08),
        iterations=25,
        initial={"viscosity": 0.006},
        progress=False,
    )
    assert res.values["viscosity"] == pytest.approx(0.01, rel=0.02)
    assert res.history["loss"][0] > 100 * res.best_loss
    res.save(tmp_path / "fit.json")
    res.plot(tmp_path / "fit.png")
    assert (tmp_path / "fit.png").stat().st_size > 1000


def test_smooth_strip_level_is_differentiable_and_matches_hard_count():
    from jaxmps.scenes import StripLevel

    case = jaxmps.scenes.hydrostatic(spacing=0.01, width=0.2, depth=0.1)
    hard = StripLevel("h", 0.1, 0.04, 0.01, 0.0)
    soft = StripLevel("s", 0.1, 0.04, 0.01, 0.0, softness=0.05)
    # Lattice columns sit at x = 0.085, 0.095, ... (l0/2 from the strip edges).
    assert float(soft(case.scene, case.state)) == pytest.approx(
        float(hard(case.scene, case.state)), rel=1e-3
    )
    assert float(hard(case.scene, case.state)) == pytest.approx(0.1)

    # Edges smoothed over a spacing: the weights' integral, not the strip's width,
    # is the width a level surface fills (before, 2 l0 read 1.31 x the depth).
    for x in (0.1, 0.1025, 0.105):
        for width in (0.02, 0.04):
            level = StripLevel("s", x, width, 0.01, 0.0, softness=1.0)
            assert float(level(case.scene, case.state)) == pytest.approx(0.1, rel=0.015)

    def depth(x):
        state = eqx.tree_at(lambda s: s.position, case.state, x)
        return StripLevel("s", 0.1, 0.04, 0.01, 0.0, softness=1.0)(case.scene, state)

    g = jax.grad(depth)(case.state.position)
    assert np.all(np.isfinite(g)) and float(jnp.abs(g).max()) > 0


@pytest.mark.slow
def test_calibrate_a_per_body_friction_coefficient():
    """A per-body field (shape (b,)) is calibrated like a scalar: a coarse sliding
    block made with mu_k = 0.45, fitted from 0.3, moves towards the truth and the
    best iterate is within 2 % after 12 Adam steps (the script in calibration/ runs
    the full-resolution case)."""
    import math

    case = jaxmps.scenes.friction_tilt(
        spacing=0.2,
        floor_length=3.0,
        settle=0.2,
        mu_static=0.45,
        angle=math.degrees(math.atan(0.6)),
    )
    truth = set_field(case.params, "rigid.mu_kinetic", jnp.asarray([0.45]))
    obs = jaxmps.scenes.observe_probes(case.probes)
    n = 200
    saved = jaxmps.simulate(case.scene, truth, case.state, n, 10, obs).saved
    curve = Curve(times=np.asarray(saved["time"]), values=np.asarray(saved["block_x"]))
    res = calibrate(
        case,
        {"rigid.mu_kinetic": Log()},
        curve,
        "block_x",
        n,
        10,
        optimiser=optax.adam(0.05),
        iterations=12,
        initial={"rigid.mu_kinetic": 0.3},
        progress=False,
    )
    assert res.history["rigid.mu_kinetic"][0] == pytest.approx(0.3)
    assert abs(res.values["rigid.mu_kinetic"] / 0.45 - 1) < 0.02
    assert res.params.rigid.mu_kinetic.shape == (1,)


def test_simulate_before_and_after_a_sweep_of_the_same_shapes(case):
    # The sweep compiles its rollout with a joint neighbour-reuse decision over its
    # batch axis; a plain simulate of the same shapes before and after must not
    # pick up that program (it would name an axis that is not there).
    obs = jaxmps.scenes.observe_probes(case.probes)
    before = jaxmps.simulate(case.scene, case.params, case.state, 20, 10, obs)
    res = jaxmps.sweep(case, {"viscosity": jnp.array([1e-6, 2e-6])}, 20, 10)
    after = jaxmps.simulate(case.scene, case.params, case.state, 20, 10, obs)
    np.testing.assert_array_equal(after.saved["front"], before.saved["front"])
    np.testing.assert_allclose(res.saved["front"][0], before.saved["front"], rtol=1e-10)


def test_sweep_checks_every_member_as_a_single_run(case):
    """A value `make_params` refuses is refused in a sweep too, naming the member."""
    with pytest.raises(ValueError, match="Params.density must be positive"):
        jaxmps.make_params(2, dt=1e-3, density=-1000.0)
    bad = {
        "density": ([1000.0, -1000.0], r"member 1 \(density=-1000.0\).*positive"),
        "viscosity": ([1e-6, np.nan], r"member 1 \(viscosity=nan\).*finite"),
        "beta": ([np.inf], r"member 0 \(beta=inf\).*in \(0, 1\]"),
    }
    for name, (values, message) in bad.items():
        with pytest.raises(ValueError, match=message):
            jaxmps.sweep(case, {name: np.asarray(values)}, n_steps=2)
    with pytest.raises(ValueError, match="'viscosity' must be numbers"):
        jaxmps.sweep(case, {"viscosity": ["thick", "thin"]}, n_steps=2)
    with pytest.raises(ValueError, match="at least one member"):
        jaxmps.sweep(case, {"viscosity": []}, n_steps=2)
    with pytest.raises(ValueError, match="Nothing to sweep"):
        jaxmps.sweep(case, {}, n_steps=2)


def test_sweep_reports_a_failed_member():
    """A member whose run fails (a time step far beyond the Courant limit, which
    only the run finds) is reported with its message; the other succeeds."""
    small = jaxmps.scenes.hydrostatic(spacing=0.05)
    dt = float(small.params.dt)
    res = jaxmps.sweep(small, {"dt": np.array([dt, 40 * dt])}, 4, 2)
    failed = res.failed()
    assert list(failed) == [1] and res.messages()[0] == "successful"
    code = int(np.asarray(res.result)[1])
    assert failed[1] == jaxmps.Result[jaxmps._result.result_from_code(code)]
    # Adaptive steps: the step beyond its limit is taken again shorter (it is
    # named first, before the escapes it causes); what ends the run then is a
    # failure that names the step too.
    assert "Courant" in failed[1] or "reduce `dt`" in failed[1]


def test_calibrate_stops_at_a_failed_rollout_and_says_which():
    """An optimiser that multiplies the viscosity by e^3 per iteration takes it
    past the viscous limit at iterate 2: the fit stops there, its status and result
    code say so, and it returns iterate 1. (Fixed steps: adaptive ones would
    shorten to the viscous limit, until below `dt_min`.)"""
    dt = float(jaxmps.scenes.hydrostatic(spacing=0.05).params.dt)
    small = jaxmps.scenes.hydrostatic(spacing=0.05, dt=dt)
    scene, dt = small.scene, float(small.params.dt)
    start = 0.2 * scene.lam / (2 * scene.dim * dt)  # viscous number 0.2
    obs = jaxmps.scenes.observe_probes(small.probes)
    tr = jaxmps.simulate(scene, small.params, small.state, 2, 1, obs)
    curve = Curve(
        times=np.asarray(tr.saved["time"]),
        values=np.asarray(tr.saved["pressure_bottom"]),
    )
    jump = optax.GradientTransformation(
        lambda params: optax.EmptyState(),
        lambda updates, state, params=None: (
            jax.tree.map(lambda g: jnp.full_like(g, 3.0), updates),
            state,
        ),
    )
    with pytest.warns(UserWarning, match=r"iterate 2 \(viscosity=.*\) failed"):
        res = calibrate(
            small,
            {"viscosity": Log()},
            curve,
            "pressure_bottom",
            2,
            1,
            optimiser=jump,
            iterations=5,
            initial={"viscosity": start},
            progress=False,
            checkpoint=False,
        )
    assert res.status == "rollout_failed" and res.iterations == 2
    assert res.result == int(jaxmps._result.result_code(jaxmps.Result.step_too_large))
    assert "viscous number" in res.message
    assert res.best_iteration == 1
    assert res.values["viscosity"] == pytest.approx(start)
    assert np.isfinite(res.best_loss)


def test_a_batch_without_one_curve_per_member_is_refused():
    """A batched fit needs one curve per member (the batch's fit against the
    mean of single fits is in test_devices.py, over two devices)."""
    from jaxmps.calibration import Identity

    case = jaxmps.scenes.dam_break(spacing=0.0146, dt=1e-3)
    gravity = np.array([[0.0, -9.81], [0.0, -5.0]])
    curve = Curve(times=np.linspace(0.005, 0.03, 6), values=np.full(6, 0.2))
    with pytest.raises(ValueError, match="sequence of 2 Curves"):
        jaxmps.calibrate(
            case,
            {"viscosity": Identity()},
            curve,
            "front",
            30,
            10,
            batch={"gravity": gravity},
        )


def test_a_damped_oscillation_fit_recovers_period_and_damping():
    """A decaying cosine sampled coarsely, with an offset and 1 % noise: the
    period within 0.1 % and the damping ratio within 0.002 of the truth, from a
    period guess 15 % off; a growing record reads a negative damping ratio."""
    from jaxmps.calibration import fit_damped_oscillation

    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 4.0, 160)
    for period, zeta in ((0.8, 0.03), (1.7, 0.1), (0.5, -0.01)):
        w = 2 * np.pi / period
        y = 0.2 + np.exp(-zeta * w * t) * (np.cos(w * t) + 0.3 * np.sin(w * t))
        y = y + 0.01 * rng.standard_normal(t.shape)
        found, damping, rms = fit_damped_oscillation(t, y, 1.15 * period)
        assert abs(found / period - 1) < 1e-3, (period, found)
        assert abs(damping - zeta) < 2e-3, (zeta, damping)
        assert 0.005 < rms < 0.015
    with pytest.raises(ValueError, match="same length"):
        fit_damped_oscillation(t, t[:-1], 1.0)
    with pytest.raises(ValueError, match="period > 0"):
        fit_damped_oscillation(t, t, -1.0)


def test_a_curve_beyond_the_rollout_or_a_start_the_transform_cannot_take_is_refused():
    """Samples after the rollout's last save would be compared with that save
    held flat; log(0) is a start no step moves. Both are refused up front,
    naming what to change; a window that leaves the late samples out is taken."""
    case = jaxmps.scenes.dam_break(spacing=0.0146, dt=2e-3)
    late = Curve(times=np.linspace(0.01, 0.8, 8), values=np.linspace(0.14, 0.3, 8))
    fit = dict(probe="front", n_steps=40, save_every=5, iterations=1, progress=False)
    with pytest.raises(ValueError, match=r"up to t=0\.8 s, beyond .* end t=0\.08 s"):
        calibrate(case, {"viscosity": Log()}, late, **fit)
    windowed = Curve(late.times, late.values, window=(0.0, 0.08))
    assert calibrate(case, {"viscosity": Log()}, windowed, **fit).iterations == 1
    with pytest.raises(ValueError, match=r"curve 1 has samples up to t=0\.8 s"):
        calibrate(
            case,
            {"viscosity": Log()},
            [windowed, late],
            batch={"dt": [2e-3, 1e-3]},
            **fit,
        )
    with pytest.raises(ValueError, match=r"'viscosity', 0\.0, must be positive"):
        calibrate(
            case, {"viscosity": Log()}, windowed, initial={"viscosity": 0.0}, **fit
        )
    with pytest.raises(ValueError, match=r"inside Bounded\(0\.1, 1\).*initial="):
        calibrate(case, {"viscosity": Bounded(0.1, 1.0)}, windowed, **fit)


@pytest.mark.slow
def test_forward_mode_calibration_takes_the_reverse_mode_steps(case):
    """`calibrate(..., autodiff="forward")`: the same losses and iterates as the
    default reverse mode, for one experiment (the dam break's adaptive steps) and
    for a batch of two (its fixed steps). (The density is not fitted beside the
    viscosity: the incompressible front does not depend on it, its derivative is
    round-off of either sign, and Adam's normalised step turns that into a move.)"""
    obs = jaxmps.scenes.observe_probes(case.probes)
    truth = set_field(case.params, "viscosity", jnp.asarray(0.01))
    tr = jaxmps.simulate(case.scene, truth, case.state, 40, 5, obs)
    curve = Curve(
        times=np.asarray(tr.saved["time"]), values=np.asarray(tr.saved["front"])
    )
    fields = {"viscosity": Log()}
    settings = dict(
        iterations=3,
        initial={"viscosity": 0.006},
        progress=False,
        optimiser=optax.adam(0.08),
    )
    fits = {
        mode: calibrate(case, fields, curve, "front", 40, 5, autodiff=mode, **settings)
        for mode in ("reverse", "forward")
    }
    np.testing.assert_allclose(
        fits["forward"].history["loss"], fits["reverse"].history["loss"], rtol=1e-9
    )
    assert fits["forward"].values["viscosity"] == pytest.approx(
        fits["reverse"].values["viscosity"], rel=1e-9
    )
    fixed = jaxmps.scenes.dam_break(spacing=0.0146, dt=1e-3)
    batch = {"gravity": np.array([[0.0, -9.81], [0.0, -8.0]])}
    batched = {
        mode: calibrate(
            fixed,
            fields,
            [curve, curve],
            "front",
            50,
            10,
            batch=batch,
            autodiff=mode,
            **settings,
        )
        for mode in ("reverse", "forward")
    }
    # Two programs' round-off: 3e-9 of the loss in the batch (measured).
    np.testing.assert_allclose(
        batched["forward"].history["loss"],
        batched["reverse"].history["loss"],
        rtol=1e-7,
    )
    with pytest.raises((ValueError, TypeError), match="autodiff"):
        calibrate(case, fields, curve, "front", 40, 5, autodiff="both", **settings)
