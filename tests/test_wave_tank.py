"""Prescribed wall motion and the piston wave maker against linear theory."""

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import small_tank

import jaxmps
from jaxmps.fluid import Harmonic, HarmonicParams, PrescribedMotion
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


def test_piston_wave_height_within_10_percent_of_linear_theory():
    """kh = 1.42, S = 1.5 cm, H_linear = 2.0 cm (H/lambda = 0.025). First-harmonic
    amplitude at 0.6 m from the piston, fitted over two periods after the ramp and
    before the reflection returns. Measured: +7.0 % at 19e84d7 (float64).

    Known weakness (benchmarks/NOTES.md §6): this single run moves with round-off.
    Perturbing the initial fluid positions by 1e-10 m, or changing the summation
    order of the pressure product (564f79e, reverted), gave -3.8 to -15 %, so the
    test can fail on a change that is exact in real arithmetic.
    """
    case = jaxmps.scenes.wave_tank(depth=0.2, stroke=0.015, tank_length=1.6, t_end=3.6)
    obs = jaxmps.scenes.observe_probes(case.probes)
    n = int(case.t_end / float(case.params.dt)) // 10 * 10
    tr = jaxmps.simulate(case.scene, case.params, case.state, n, 10, obs)
    t = np.asarray(tr.saved["time"])
    eta = np.asarray(tr.saved["eta"])
    period = case.config["wave_period"]
    window = (t >= 2.0) & (t < 3.6)
    basis = np.c_[
        np.cos(2 * np.pi * t[window] / period),
        np.sin(2 * np.pi * t[window] / period),
        np.ones(window.sum()),
    ]
    coef, *_ = np.linalg.lstsq(basis, eta[window], rcond=None)
    height = 2 * np.hypot(coef[0], coef[1])
    assert height == pytest.approx(case.config["linear_wave_height"], rel=0.10)


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
