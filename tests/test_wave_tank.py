"""Prescribed wall motion and the piston wave maker against linear theory."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import small_tank

import jaxmps
from jaxmps.fluid import Harmonic, HarmonicParams, PrescribedMotion
from jaxmps.scenes import StripLevel
from jaxmps.scenes._wave_tank import linear_wave_number, piston_height_ratio


def test_linear_wave_maker_theory_values():
    # Deep-water limit: H/S -> 2; shallow: H/S -> kh (Dean & Dalrymple Fig. 6.4).
    assert piston_height_ratio(50.0, 1.0) == pytest.approx(2.0, rel=1e-6)
    assert piston_height_ratio(0.01, 1.0) == pytest.approx(0.01, rel=1e-3)
    k = linear_wave_number(0.8, 0.2, 9.81)
    assert (2 * math.pi / 0.8) ** 2 == pytest.approx(9.81 * k * math.tanh(0.2 * k))


def test_harmonic_wall_motion_is_exact_and_drift_free():
    scene, params, state = small_tank()
    walls = tuple(int(i) for i in np.nonzero(np.asarray(state.kind) != 0)[0])
    motion = PrescribedMotion(particles=walls, axis=(1.0, 0.0), law=Harmonic())
    scene = eqx.tree_at(lambda s: s.motion, scene, motion, is_leaf=lambda x: x is None)
    amp, freq = 0.004, 2.0
    params = eqx.tree_at(
        lambda p: p.motion,
        params,
        HarmonicParams(amplitude=amp, frequency=freq),
        is_leaf=lambda x: x is None,
    )
    tr = jaxmps.simulate(scene, params, state, 40, 20)
    t = float(tr.state.time)
    shift = amp * math.sin(2 * math.pi * freq * t)
    idx = jnp.asarray(walls)
    np.testing.assert_allclose(
        tr.state.position[idx, 0], state.position[idx, 0] + shift, atol=1e-12
    )
    np.testing.assert_allclose(tr.state.position[idx, 1], state.position[idx, 1])
    # Velocity is the step's mean velocity (X(t) - X(t - dt)) / dt.
    dt = float(params.dt)
    expected = (shift - amp * math.sin(2 * math.pi * freq * (t - dt))) / dt
    np.testing.assert_allclose(tr.state.velocity[idx, 0], expected, rtol=1e-9)


GAUGES = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8)  # [m] from the piston's rest position


def incident_wave_height(t, x, eta, period, k):
    """Height of the incident (+x) wave at frequency 2 pi / period and wave number
    k, separated from the reflected (-x) one by least squares over gauges at x
    (Mansard & Funke 1980, with k fixed by linear dispersion): eta(x, t) =
    Re[a_i e^{i(w t - k x)} + a_r e^{i(w t + k x)}] + a mean level per gauge.
    Returns (2 |a_i|, |a_r| / |a_i|)."""
    w = 2 * np.pi / period
    tt, xx = np.meshgrid(t, x, indexing="ij")
    columns = [
        np.cos(w * tt - k * xx),
        np.sin(w * tt - k * xx),
        np.cos(w * tt + k * xx),
        np.sin(w * tt + k * xx),
    ] + [(xx == g).astype(float) for g in x]
    basis = np.stack([c.ravel() for c in columns], axis=1)
    coef, *_ = np.linalg.lstsq(basis, eta.ravel(), rcond=None)
    incident, reflected = np.hypot(*coef[0:2]), np.hypot(*coef[2:4])
    return 2 * incident, reflected / incident


def test_incident_wave_separation_recovers_synthetic_waves():
    period, k = 0.8, 7.1
    t = np.linspace(2.0, 3.6, 400)
    x = np.asarray(GAUGES)
    tt, xx = np.meshgrid(t, x, indexing="ij")
    w = 2 * np.pi / period
    eta = (
        0.01 * np.cos(w * tt - k * xx + 0.3)
        + 0.002 * np.sin(w * tt + k * xx)
        + 0.001 * xx
    )
    height, reflection = incident_wave_height(t, x, eta, period, k)
    assert height == pytest.approx(0.02, rel=1e-9)
    assert reflection == pytest.approx(0.2, rel=1e-9)


@pytest.mark.long
def test_piston_wave_height_against_linear_theory():
    """kh = 1.42, l0 = 1 cm (20 particles deep), two strokes in one vmapped run:
    S = 1.5 and 3 cm (H_linear = 2.0 and 4.0 cm, H/lambda = 0.023 and 0.045). The
    incident first harmonic is separated from the far wall's reflection over six
    gauges 0.3-0.8 m from the piston, over two periods after the ramp.

    Linear piston theory is the inviscid, leak-free ideal, so the simulated wave
    may fall below it (numerical damping on the way to the gauges), not above.
    Measured (float64, at 3c5e877): this run gives 0.84 and 0.93 of linear theory
    (mean 0.88); four round-off-level perturbations of the initial positions
    (1e-10 m) gave means of 0.89-0.94. Each stroke alone spreads over 0.86-0.98;
    at l0 = 5 mm one run gave 0.93. A single gauge is not a measurement here: the
    reflection (~10 % of the incident amplitude inside the window) modulates the
    height along the tank by +-10 %, and the earlier single-gauge test at 0.6 m
    (limit 10 %) passed near an antinode, by -15 % to +7 % with round-off.
    """
    cases = [
        jaxmps.scenes.wave_tank(depth=0.2, stroke=s, tank_length=1.6, t_end=3.6)
        for s in (0.015, 0.03)
    ]
    # One geometry (the larger stroke's, whose bed reaches further behind the
    # piston) and each stroke's motion table.
    scene, state = cases[1].scene, cases[1].state
    params = jax.tree.map(lambda *p: jnp.stack(p), *[c.params for c in cases])
    l0 = cases[0].config["spacing"]
    probes = tuple(StripLevel(f"eta_{x}", x, 5 * l0, l0, 0.2) for x in GAUGES)
    observe = jaxmps.scenes.observe_probes(probes)
    t_end = cases[0].t_end
    n = int(t_end / float(cases[0].params.dt)) // 10 * 10

    def run(p):
        return jaxmps.simulate(scene, p, state, n, 10, observe, throw=False)

    tr = jax.vmap(run)(params)
    assert np.all(np.asarray(tr.result == jaxmps.Result.successful))
    t = np.asarray(tr.saved["time"][0])
    window = (t >= 2.0) & (t < t_end)
    ratios = []
    for member, case in enumerate(cases):
        eta = np.stack([np.asarray(tr.saved[p.name][member]) for p in probes], 1)
        height, reflection = incident_wave_height(
            t[window],
            np.asarray(GAUGES),
            eta[window],
            case.config["wave_period"],
            case.config["wave_number"],
        )
        assert reflection < 0.3
        ratios.append(height / case.config["linear_wave_height"])
    assert 0.80 < np.mean(ratios) < 1.05, ratios


def test_beach_geometry_and_short_run():
    case = jaxmps.scenes.wave_tank(end="beach", tank_length=1.0, depth=0.1, t_end=0.2)
    x = np.asarray(case.state.position)
    kind = np.asarray(case.state.kind)
    slope = case.config["beach_slope"]
    toe = case.config["tank_length"] - case.config["depth"] * slope * 1.2
    fluid = kind == int(jaxmps.Kind.FLUID)
    surface = (x[:, 0] - toe) / slope
    on_beach = (x[:, 0] > toe) & (x[:, 0] < case.config["tank_length"])
    # No fluid below the beach surface; pressure walls line it.
    assert np.all(x[fluid & on_beach, 1] >= surface[fluid & on_beach])
    walls = (kind == int(jaxmps.Kind.WALL)) & on_beach & (x[:, 1] > 0)
    assert walls.sum() > 10
    assert np.all(np.abs(x[walls, 1] - surface[walls]) < 1.5 * case.config["spacing"])
    tr = jaxmps.simulate(case.scene, case.params, case.state, 60, 60)
    assert int(tr.state.active.sum()) == int(case.state.active.sum())


def test_no_ramp_drives_the_full_stroke_from_the_start():
    """ramp_periods = 0 is a stroke at full amplitude from t = 0 (it once divided
    0 by 0 and fed the piston NaN)."""
    case = jaxmps.scenes.wave_tank(ramp_periods=0.0)
    motion = case.params.motion
    times, stroke = np.asarray(motion.times), np.asarray(motion.stroke)
    assert np.all(np.isfinite(stroke))
    half = 0.5 * case.config["stroke"]
    period = case.config["wave_period"]
    np.testing.assert_allclose(stroke, half * np.sin(2 * np.pi * times / period))


def test_deep_water_theory_stays_finite_and_unresolved_waves_are_refused():
    """The dispersion relation and the piston's height ratio hold in deep water
    (cosh 2kh beyond floats once overflowed), and a wave shorter than a few
    particle spacings is refused by its period."""
    k = linear_wave_number(0.3, 0.2, 9.81)
    assert (2 * math.pi / 0.3) ** 2 == pytest.approx(9.81 * k * math.tanh(0.2 * k))
    assert piston_height_ratio(1e4, 1.0) == 2.0
    with pytest.raises(ValueError, match=r"wave_period=0.001 s makes waves .* long"):
        jaxmps.scenes.wave_tank(wave_period=0.001)
