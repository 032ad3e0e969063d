"""Explicit MPS (E-MPS, seed 002 §2): constants, hydrostatics, dam break, time-step
limit, gradients."""

import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps.operators import EMPSGradientWeight, EMPSWeight, reference_constants

DATA = pathlib.Path(__file__).parent / "data"


def test_emps_reference_constants():
    """Seed 002 digest §2.2 (square lattice, r_e = 2.1 l0)."""
    n0, lam = reference_constants(EMPSWeight(), 2, 2.1)
    n0_grad, _ = reference_constants(EMPSGradientWeight(), 2, 2.1)
    assert n0 == pytest.approx(2.9477, abs=1e-4)
    assert lam == pytest.approx(1.2246, abs=1e-4)
    assert n0_grad == pytest.approx(10.1317, abs=1e-4)


def test_explicit_hydrostatic_pressure_time_averaged_within_5_percent():
    case = jaxmps.scenes.hydrostatic(solver="explicit", spacing=0.01, width=0.2)
    obs = jaxmps.scenes.observe_probes(case.probes)
    n = int(1.0 / float(case.params.dt)) // 50 * 50
    tr = jaxmps.simulate(case.scene, case.params, case.state, n, 50, obs)
    p = {k: np.asarray(v)[25:].mean() for k, v in tr.saved.items()}
    rho_g = 1000.0 * 9.81
    # As for the semi-implicit test: probes at y = l0/2..., effective surface H - l0/2.
    assert p["pressure_bottom"] == pytest.approx(rho_g * (0.2 - 0.005), rel=0.05)
    assert p["pressure_middle"] == pytest.approx(rho_g * (0.195 - 0.1), rel=0.05)
    assert float(jnp.abs(tr.state.velocity).max()) < 0.2


def test_facing_wall_pressure_is_that_of_the_nearest_fluid_particle(rng):
    """wall_pressure='facing' (seed 002 Ch. 5): each wall particle takes the
    pressure of its nearest fluid particle within r_e (0 with none), checked by
    brute force on a jittered tank (no ties); every other pressure is the
    equation of state's."""
    case = jaxmps.scenes.hydrostatic(
        solver="explicit", spacing=0.02, width=0.2, depth=0.2, wall_pressure="facing"
    )
    scene, state = case.scene, case.state
    fluid = np.asarray((state.kind == 0) & state.active)
    jitter = rng.normal(0, 0.05 * 0.02, state.position.shape)
    x = state.position + jnp.asarray(np.where(fluid[:, None], jitter, 0.0))
    nbrs = jaxmps.neighbours.build(
        scene.grid, x, state.active, scene.max_neighbours, scene.r_e
    )
    pairs = jaxmps.operators.make_pairs(nbrs.index, x, scene.weight, scene.r_e)
    inputs = jaxmps.fluid.PressureInputs(
        pairs=pairs,
        n_star=jaxmps.operators.number_density(pairs),
        position=x,
        velocity=state.velocity,
        surface=jnp.zeros_like(state.active),
        pairs_k=pairs,
        velocity_k=state.velocity,
        pressure_k=state.pressure,
        kind=state.kind,
        active=state.active,
    )
    disc = scene.discretisation
    facing = np.asarray(
        scene.solver(disc, scene.laplacian, scene.grid, case.params, inputs).pressure
    )
    plain = jaxmps.Explicit()(
        disc, scene.laplacian, scene.grid, case.params, inputs
    ).pressure
    plain = np.asarray(plain)
    wall = np.asarray((state.kind == int(jaxmps.Kind.WALL)) & state.active)
    xs = np.asarray(x)
    expected = plain.copy()
    for i in np.nonzero(wall)[0]:
        r = np.linalg.norm(xs[fluid] - xs[i], axis=1)
        near = r < scene.r_e
        expected[i] = plain[fluid][np.argmin(r)] if near.any() else 0.0
    assert np.count_nonzero(expected[wall]) > 10
    np.testing.assert_array_equal(facing, expected)


def test_facing_wall_pressure_holds_the_hydrostatic_bottom_pressure():
    """With the walls given the facing fluid's pressure, the time-averaged
    pressure at the bottom of a still tank is within 2 % of rho g (H - l0/2)
    (the equation-of-state walls: 3.5 % short, `test_explicit_hydrostatic_...`),
    and no fluid particle crosses the floor."""
    case = jaxmps.scenes.hydrostatic(
        solver="explicit", spacing=0.01, width=0.2, wall_pressure="facing"
    )
    obs = jaxmps.scenes.observe_probes(case.probes)
    n = int(1.0 / float(case.params.dt)) // 50 * 50
    tr = jaxmps.simulate(case.scene, case.params, case.state, n, 50, obs)
    p = {k: np.asarray(v)[25:].mean() for k, v in tr.saved.items()}
    rho_g = 1000.0 * 9.81
    assert p["pressure_bottom"] == pytest.approx(rho_g * (0.2 - 0.005), rel=0.02)
    assert p["pressure_middle"] == pytest.approx(rho_g * (0.195 - 0.1), rel=0.02)
    fluid = np.asarray(tr.state.kind) == 0
    assert np.asarray(tr.state.position)[fluid, 1].min() > 0.0


def test_wall_pressure_is_an_explicit_option_named_in_its_refusals():
    with pytest.raises(ValueError, match=r"wall_pressure='mirror' is not available"):
        jaxmps.scenes.hydrostatic(solver="explicit", wall_pressure="mirror")
    with pytest.raises(ValueError, match=r"use solver=explicit"):
        jaxmps.scenes.hydrostatic(wall_pressure="facing")
    with pytest.raises(ValueError, match=r"valid: \('equation', 'facing'\)"):
        jaxmps.Explicit(wall_pressure="nearest")


def test_time_step_beyond_sound_speed_limit_is_refused_unless_opted_out():
    case = jaxmps.scenes.hydrostatic(
        solver="explicit", spacing=0.02, width=0.1, depth=0.1, dt=1e-3
    )
    too_big = eqx.tree_at(lambda p: p.dt, case.params, jnp.asarray(5e-3))
    with pytest.raises(ValueError, match=r"dt < 0.8 l0 / c = 0.0016 s"):
        jaxmps.simulate(case.scene, too_big, case.state, 2, 2)
    opted_out = eqx.tree_at(
        lambda s: s.solver, case.scene, jaxmps.Explicit(check_time_step=False)
    )
    tr = jaxmps.simulate(opted_out, too_big, case.state, 2, 2, throw=False)
    assert tr.result == jaxmps.Result.step_too_large


def _series(name, series):
    rows = [
        line.split(",")
        for line in (DATA / name).read_text().splitlines()
        if line and not line.startswith("#")
    ][1:]
    return np.array([(float(r[-2]), float(r[-1])) for r in rows if r[0] == series]).T


def test_explicit_dam_break_front():
    """Gates A (0.95-1.25 x Martin & Moyce) and B (front speed) of REFERENCE.md §1,
    20 particles across the column. Measured: +16/+14/+9/+7 % at T = 1/1.5/2/2.5."""
    case = jaxmps.scenes.dam_break(solver="explicit", spacing=0.0073)
    obs = jaxmps.scenes.observe_probes(case.probes)
    n = int(0.23 / float(case.params.dt)) // 10 * 10
    tr = jaxmps.simulate(case.scene, case.params, case.state, n, 10, obs)
    a = case.config["column_width"]
    t = np.asarray(tr.saved["time"]) * np.sqrt(2 * 9.81 / a)
    z = np.asarray(tr.saved["front"]) / a
    mm_t, mm_z = _series("martin_moyce_1952_surge_front.csv", "mm_a2.25_tab")
    for T in (1.0, 1.5, 2.0, 2.5):
        assert 0.95 <= np.interp(T, t, z) / np.interp(T, mm_t, mm_z) <= 1.25
    speed = np.interp(2.5, t, z) - np.interp(1.5, t, z)
    assert 0.9 <= speed <= 1.6


@pytest.mark.parametrize("field", ["sound_speed", "viscosity"])
def test_explicit_rollout_gradient_matches_finite_differences(field):
    # Fixed steps: adaptive ones would follow the sound speed, which finite
    # differences see and the gradient does not (the dt is a constant to it).
    case = jaxmps.scenes.hydrostatic(
        solver="explicit",
        spacing=0.01,
        width=0.06,
        depth=0.06,
        viscosity=1e-2,
        dt=4e-4,
    )
    state = case.state
    fluid = (state.kind == 0)[:, None]
    swirl = jnp.stack([-(state.position[:, 1] - 0.03), state.position[:, 0] - 0.03], -1)
    state = eqx.tree_at(lambda s: s.velocity, state, jnp.where(fluid, 0.5 * swirl, 0.0))

    def loss(value):
        params = eqx.tree_at(lambda p: getattr(p, field), case.params, value)
        final = jaxmps.simulate(case.scene, params, state, 12, 4, throw=False).state
        f = state.kind == 0
        return jnp.sum(jnp.where(f, final.pressure, 0.0)) * 1e-3 + jnp.sum(
            jnp.where(f[:, None], final.position, 0.0) ** 2
        )

    x0 = getattr(case.params, field)
    g = jax.grad(loss)(x0)
    h = 1e-4 * x0
    fd = (loss(x0 + h) - loss(x0 - h)) / (2 * h)
    assert abs(float(fd)) > 0
    assert float(g) == pytest.approx(float(fd), rel=1e-4)
