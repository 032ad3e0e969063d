"""The edges of the safe region: accurate just inside a stability limit, a clear
error just past it, nothing lost when a run stops, and bad input refused by name."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import io
from jaxmps.cli import main


def _tank(**overrides):
    return jaxmps.scenes.hydrostatic(spacing=0.02, width=0.2, depth=0.2, **overrides)


def _bottom_pressure_error(case, t_end=0.5):
    """Relative error of the bottom probe's mean pressure over [t_end/2, t_end]
    against `scenes.hydrostatic_pressure` (rho g (H - y_p), y_p the probe
    particles' mean initial height)."""
    dt = float(case.params.dt)
    n = int(round(t_end / dt / 10)) * 10
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        n,
        10,
        jaxmps.scenes.observe_probes(case.probes),
        throw=False,
    )
    saved = {k: np.asarray(v) for k, v in out.saved.items()}
    reference = jaxmps.scenes.hydrostatic_pressure(case)
    late = saved["time"] >= 0.5 * t_end
    return out.result, np.mean(saved["pressure_bottom"][late]) / reference - 1


def _viscosity_for(case, number):
    """The viscosity giving viscous number 2 d nu dt / lambda = `number`."""
    scene = case.scene
    return number * scene.lam / (2 * scene.dim * float(case.params.dt))


# ------------------------------------------------------------ viscous limit


def test_just_inside_the_viscous_limit_stays_hydrostatic():
    """Viscous number 0.95 (limit 1; measured onset of instability ~1.5): stable,
    and the bottom pressure within 2 % of hydrostatic (1.0 % measured)."""
    base = _tank()
    case = _tank(viscosity=_viscosity_for(base, 0.95))
    result, error = _bottom_pressure_error(case)
    assert result == jaxmps.Result.successful
    assert abs(error) < 0.02


def test_past_the_viscous_limit_is_refused_or_reported():
    base = _tank()
    viscosity = _viscosity_for(base, 1.2)
    # Adaptive steps (the default) take at most half the viscous limit.
    adaptive = _tank(viscosity=viscosity)
    tr = jaxmps.simulate(
        adaptive.scene, adaptive.params, adaptive.state, 2, 2, throw=False
    )
    assert tr.result == jaxmps.Result.successful
    assert float(tr.steps.dt_max[0]) == pytest.approx(0.5 * float(base.params.dt) / 1.2)
    # A fixed step beyond it is refused, or reported when traced.
    case = _tank(viscosity=viscosity, dt=float(base.params.dt))
    with pytest.raises(ValueError, match=r"viscous stability limit.*Reduce `dt`"):
        jaxmps.simulate(case.scene, case.params, case.state, 2, 2)
    # Traced (a sweep, a gradient): the run ends with the result code instead.
    run = jax.jit(
        lambda p: jaxmps.simulate(case.scene, p, case.state, 2, 2, throw=False).result
    )
    assert run(case.params) == jaxmps.Result.step_too_large
    assert "viscous number" in jaxmps.Result[jaxmps.Result.step_too_large]


# ------------------------------------------------------------ sound-speed limit


def test_explicit_dt_past_the_sound_limit_is_refused_or_reported():
    base = _tank(solver="explicit")
    case = _tank(solver="explicit", dt=float(base.params.dt))
    limit = case.scene.solver.max_dt(case.scene.spacing, float(case.params.sound_speed))
    params = eqx.tree_at(lambda p: p.dt, case.params, jnp.asarray(1.05 * limit))
    with pytest.raises(ValueError, match=r"explicit \(E-MPS\) stability limit"):
        jaxmps.simulate(case.scene, params, case.state, 2, 2)
    run = jax.jit(
        lambda p: jaxmps.simulate(case.scene, p, case.state, 2, 2, throw=False).result
    )
    assert run(params) == jaxmps.Result.step_too_large


@pytest.mark.parametrize("dt", [0.5, 2.0])
def test_a_step_that_carries_particles_beyond_r_e_is_named_as_the_step(dt):
    """Gravity alone moves the water g dt^2 (10-200 spacings) in the first step:
    its searches overflow or lose particles, but the failure named is the step,
    whose velocity at the end (the pressure holds the water) passes the Courant
    test."""
    case = jaxmps.scenes.hydrostatic(spacing=0.05, dt=dt)
    tr = jaxmps.simulate(case.scene, case.params, case.state, 1, 1, throw=False)
    assert tr.result == jaxmps.Result.step_too_large
    assert "beyond r_e in one step" in jaxmps.Result[tr.result]


# ------------------------------------------------------------ pressure solve


def test_pressure_solve_that_cannot_converge_ends_the_run_clearly(tmp_path):
    """Too few CG iterations: the run stops at the first save with the message
    naming `max_iterations`; it does not hang, and the file keeps the frames."""
    case = _tank(max_iterations=3)
    with pytest.raises(RuntimeError, match="max_iterations"):
        jaxmps.run(case, t_end=0.1, save_every=0.02, out=tmp_path / "p.h5")
    data = io.read_run(tmp_path / "p.h5")
    assert data.frames["time"][0] == 0.0
    assert int(data.state["result"]) == 0


# ------------------------------------------------------------ nothing lost


def _escaping(domain_margin=None, escape_limit=0):
    """The tank with one surface particle thrown upwards at 2.5 m/s: it leaves the
    domain (the grid box, top at 0.377 m: whole cells of (r_e + skin) / 2) at
    t ~ 0.1 s, between steps 20 and 25, unless the domain is taller. Fixed steps of
    the scene's largest step, to count them."""
    dt = float(jaxmps.scenes.hydrostatic(spacing=0.04).params.dt)
    case = jaxmps.scenes.hydrostatic(
        spacing=0.04, domain_margin=domain_margin, dt=dt, escape_limit=escape_limit
    )
    fluid = np.nonzero(np.asarray(case.state.kind) == int(jaxmps.Kind.FLUID))[0]
    top = int(fluid[np.argmax(np.asarray(case.state.position)[fluid, 1])])
    velocity = case.state.velocity.at[top].set(jnp.array([0.0, 2.5]))
    return eqx.tree_at(lambda c: c.state.velocity, case, velocity)


def test_failed_run_keeps_frames_and_last_good_state_and_restarts(tmp_path):
    path = tmp_path / "escape.h5"
    case = _escaping()
    dt = float(case.params.dt)
    save = 5 * dt
    with pytest.raises(RuntimeError, match=r"left the domain.*domain_margin"):
        jaxmps.run(case, t_end=0.4, save_every=save, out=path, chunk_saves=20)
    data = io.read_run(path)
    steps = data.frames["step"]
    # The initial frame, the four good saves, and the state at the failed step
    # (steps 21-25: in the fifth save interval).
    np.testing.assert_array_equal(steps[:5], 5 * np.arange(5))
    assert len(steps) == 6 and 20 < steps[5] <= 25, steps
    # /state is the last good save's state, not the start of the failed chunk.
    assert int(data.state["step"]) == 20
    assert int(data.state["result"]) == 0
    np.testing.assert_array_equal(data.state["position"], data.frames["position"][4])

    # Restart with a taller domain (a changed setting): it continues from step 20
    # and the failed frame is replaced.
    taller = _escaping(domain_margin=1.0)
    rest = jaxmps.run(
        taller, t_end=0.3, save_every=save, out=path, restart=True, chunk_saves=20
    )
    # To t_end exactly: saves of 5 steps to 70 dt, and a last one of 4.28 dt
    # made of 3 steps of dt and two of 0.64 dt (the last two evened out).
    assert 0.3 / dt == pytest.approx(74.28, abs=0.01)
    assert int(rest.state.step) == 75 and float(rest.state.time) == 0.3
    frames = io.read_run(path).frames
    steps = frames["step"]
    assert np.all(np.diff(steps) > 0) and steps[5] == 25 and steps[-1] == 75
    np.testing.assert_allclose(frames["dt_max"][-1], dt, rtol=1e-9)
    np.testing.assert_allclose(frames["dt_min"][-1], 0.64 * dt, rtol=0.01)


def test_spray_within_the_escape_limit_is_taken_out_and_counted():
    case = _escaping(escape_limit=1)
    top = int(np.argmax(np.asarray(case.state.velocity)[:, 1]))
    tr = jaxmps.simulate(case.scene, case.params, case.state, times=[0.3])
    assert tr.result == jaxmps.Result.successful
    assert int(tr.state.escaped) == 1 and not bool(tr.state.active[top])
    n_active = int(np.sum(np.asarray(case.state.active)))
    assert int(np.sum(np.asarray(tr.state.active))) == n_active - 1
    # The same spray with another particle thrown out: beyond the limit.
    second = int(np.nonzero(np.asarray(case.state.kind) == 0)[0][-2])
    two = eqx.tree_at(
        lambda c: c.state.velocity,
        case,
        case.state.velocity.at[second].set(jnp.array([0.0, 2.5])),
    )
    tr = jaxmps.simulate(two.scene, two.params, two.state, times=[0.3], throw=False)
    assert tr.result == jaxmps.Result.left_domain
    assert "escape_limit" in jaxmps.Result[tr.result]
    # Scenes allow a tenth of their fluid by default.
    default = jaxmps.scenes.hydrostatic(spacing=0.04)
    fluid = int(np.sum(np.asarray(default.state.kind) == 0))
    assert default.scene.escape_limit == math.ceil(0.1 * fluid)


def test_cli_restart_with_a_changed_time_step(tmp_path, capsys):
    path = tmp_path / "h.h5"
    common = ["--quiet", "--save-every", "0.01"]
    assert (
        main(
            ["run", "hydrostatic", "--set", "spacing=0.04", "--t-end", "0.02"]
            + common
            + ["--out", str(path)]
        )
        == 0
    )
    assert (
        main(
            ["run", "--restart", str(path), "--set", "dt=0.002", "--t-end", "0.04"]
            + common
        )
        == 0
    )
    data = io.read_run(path)
    # Saves at exact times; after the restart, 5 steps of the new fixed dt each.
    np.testing.assert_array_equal(data.frames["time"], [0, 0.01, 0.02, 0.03, 0.04])
    steps = data.frames["step"]
    np.testing.assert_array_equal(np.diff(steps)[2:], [5, 5])
    assert float(data.state["time"]) == 0.04
    assert np.all(data.frames["dt_max"][3:] == 0.002)
    assert float(data.attrs["dt"]) == 0.002  # a later restart keeps the new dt
    assert "restart from" in capsys.readouterr().out


def test_truncated_run_file(tmp_path, capsys):
    path = tmp_path / "run.h5"
    case = jaxmps.scenes.hydrostatic(spacing=0.04)
    jaxmps.run(case, t_end=0.02, out=path, progress=False)
    size = path.stat().st_size
    with open(path, "r+b") as f:
        f.truncate(size // 2)
    with pytest.raises(ValueError, match=r"run\.h5.*truncated, corrupt"):
        io.read_run(path)
    with pytest.raises(ValueError, match=r"run\.h5"):
        io.load_state(path, case)
    with pytest.raises(SystemExit) as exit_:
        main(["run", "--restart", str(path), "--quiet"])
    assert exit_.value.code == 2
    assert "truncated" in capsys.readouterr().err


# ------------------------------------------------------------ bad input


def _sweep_unknown(name="viscosty"):
    case = jaxmps.scenes.hydrostatic(spacing=0.05)
    jaxmps.sweep(case, {name: np.array([1e-6, 2e-6])}, 2, 2)


def _batched_params_without_vmap():
    case = jaxmps.scenes.hydrostatic(spacing=0.05)
    params = eqx.tree_at(lambda p: p.viscosity, case.params, jnp.full(3, 1e-6))
    jaxmps.simulate(case.scene, params, case.state, 2, 2)


def _vmapped_gravity_of_the_wrong_dimension():
    case = jaxmps.scenes.hydrostatic(spacing=0.05)
    batch = jax.tree.map(lambda x: jnp.stack([x, x]), case.params)
    batch = eqx.tree_at(lambda p: p.gravity, batch, jnp.zeros((2, 3)))
    jax.vmap(lambda p: jaxmps.simulate(case.scene, p, case.state, 2, 2))(batch)


def _rigid_density_per_body_wrong():
    case = jaxmps.scenes.floating_box(spacing=0.04)
    params = eqx.tree_at(lambda p: p.rigid.density, case.params, jnp.ones(2))
    jaxmps.simulate(case.scene, params, case.state, 2, 2)


def _overlapping_bodies():
    l0 = 0.01
    a = jaxmps.geometry.block([0.1, 0.1], [0.14, 0.14], l0)
    b = a + 0.3 * l0  # a second block shifted by less than half a spacing
    position = np.concatenate([a, b])
    scene = jaxmps.make_scene(position, l0, ([0, 0], [1, 1]))
    params = jaxmps.make_params(2, dt=1e-3)
    state = jaxmps.make_state(scene, position, np.zeros(len(position), int))
    body = np.repeat([0, 1], len(a))
    jaxmps.add_rigid_bodies(scene, params, state, body, density=500.0)


def _body_outside_the_tank():
    jaxmps.make_scene(np.array([[0.1, 0.1], [0.1, 5.0]]), 0.01, ([0, 0], [1, 1]))


BAD_INPUTS = {
    "negative spacing": (
        lambda: jaxmps.scenes.hydrostatic(spacing=-0.01),
        "spacing must be positive",
    ),
    "spacing given as text (--set spacing=abc)": (
        lambda: jaxmps.scenes.hydrostatic(spacing="abc"),
        r"'spacing' of scene 'hydrostatic' expects a number, got 'abc'",
    ),
    "non-whole dim": (
        lambda: jaxmps.scenes.hydrostatic(dim=2.5),
        "expects a whole number",
    ),
    "the old per-cell capacity setting": (
        lambda: jaxmps.scenes.hydrostatic(cell_capacity=20),
        "cell_capacity was replaced by candidate_capacity",
    ),
    "a neighbour stencil reaching no cells": (
        lambda: jaxmps.make_scene(
            [[0.0, 0.0], [0.1, 0.0]], 0.1, ([-1, -1], [1, 1]), reach=0
        ),
        "reach must be a positive integer",
    ),
    "a flag given a number": (
        lambda: jaxmps.scenes.flume(initial_fill=3),
        "expects true or false",
    ),
    "zero particles": (
        lambda: jaxmps.make_scene(np.zeros((0, 2)), 0.01, ([0, 0], [1, 1])),
        "no particles",
    ),
    "a particle without a place (NaN)": (
        lambda: jaxmps.make_scene(
            np.array([[0.1, 0.1], [np.nan, 0.2]]), 0.01, ([0, 0], [1, 1])
        ),
        r"position holds non-finite coordinates \(rows \[1\]\)",
    ),
    "unknown scene": (lambda: jaxmps.scenes.build("dambreak"), "Available scenes"),
    "unknown parameter": (
        lambda: jaxmps.scenes.hydrostatic(widht=0.2),
        r"Unknown parameter.*widht.*Valid parameters",
    ),
    "unknown solver": (
        lambda: jaxmps.scenes.hydrostatic(solver="implicit"),
        "solver='implicit' is not available",
    ),
    "unknown preconditioner": (
        lambda: jaxmps.scenes.hydrostatic(preconditioner="ilu"),
        r"preconditioner='ilu' is not available; valid: \('multigrid', 'jacobi'\)",
    ),
    "multigrid over-correction of 2 or more": (
        lambda: jaxmps.fluid.Multigrid(correction=2.0),
        r"Multigrid.correction must lie in \(0, 2\)",
    ),
    "explicit with the high-accuracy scheme": (
        lambda: jaxmps.scenes.hydrostatic(solver="explicit", scheme="high_accuracy"),
        "use solver=semi_implicit",
    ),
    "negative dt": (lambda: jaxmps.make_params(2, dt=-1e-3), "dt must be positive"),
    "gravity given as a negative magnitude": (
        lambda: jaxmps.make_params(2, dt=1e-3, gravity=-9.81),
        r"gravity is its magnitude .* got -9\.81 \(another direction: set "
        "Params.gravity",
    ),
    "Params of five dimensions": (
        lambda: jaxmps.make_params(5, dt=1e-3),
        "dim must be 2 or 3, got 5",
    ),
    "a surface threshold beyond 1, swept": (
        lambda: jaxmps.sweep(
            jaxmps.scenes.hydrostatic(spacing=0.05), {"beta": [0.97, 1.5]}, 2, 2
        ),
        r"Sweep member 1 \(beta=1.5\): Params.beta must be in \(0, 1\], got 1.5",
    ),
    "a negative surface threshold set by hand (a float, not an array)": (
        lambda: jaxmps.simulate(
            *(
                lambda c: (
                    c.scene,
                    eqx.tree_at(lambda p: p.beta, c.params, -1.0),
                    c.state,
                )
            )(jaxmps.scenes.hydrostatic(spacing=0.05)),
            2,
            2,
        ),
        r"Params.beta must be in \(0, 1\], got -1.0",
    ),
    "capacity below the particle count": (
        lambda: jaxmps.make_scene(
            np.zeros((4, 2)) + 0.5, 0.01, ([0, 0], [1, 1]), capacity=2
        ),
        "capacity=2 is below the 4 initial particles",
    ),
    "a particle outside the domain": (
        _body_outside_the_tank,
        "outside the domain box.*domain_margin",
    ),
    "overlapping bodies": (_overlapping_bodies, "Body 0 overlaps"),
    "CG tolerance out of range": (
        lambda: jaxmps.SemiImplicit(rtol=2.0),
        r"rtol must lie in \(0, 1\)",
    ),
    "standing-wave amplitude beyond the depth": (
        lambda: jaxmps.scenes.standing_wave(amplitude=0.6),
        "amplitude=0.6 must lie in",
    ),
    "a standing wave shorter than 8 spacings": (
        lambda: jaxmps.scenes.standing_wave(spacing=0.05, mode_number=50),
        r"mode_number=50 makes a wave 0.04 m long .* under 8 particle spacings",
    ),
    "water deeper than the shaken tank's walls": (
        lambda: jaxmps.scenes.sloshing_tank(spacing=0.05, depth=0.8),
        r"depth=0.8 m fills the tank \(tank_height=0.6 m\)",
    ),
    "a piston stroke whose waves overtop the tank": (
        lambda: jaxmps.scenes.wave_tank(spacing=0.05, stroke=3.0),
        r"stroke=3 m makes linear waves 2.63 m high .* shorten stroke \(at most",
    ),
    "sweep over a misspelt field": (
        _sweep_unknown,
        "Unknown Params field 'viscosty'.*Did you mean 'viscosity'",
    ),
    "sweep over a scene setting": (
        lambda: _sweep_unknown("porous_porosity"),
        "Unknown Params field 'porous_porosity'.*scene setting.*one case per value",
    ),
    "batched Params passed without vmap": (
        _batched_params_without_vmap,
        r"Params.viscosity has shape \(3,\).*jaxmps.sweep",
    ),
    "vmapped Params with 3-D gravity in a 2-D scene": (
        _vmapped_gravity_of_the_wrong_dimension,
        r"Params.gravity has shape \(3,\), expected \(2,\)",
    ),
    "one rigid density for a one-body scene given twice": (
        _rigid_density_per_body_wrong,
        r"Params.rigid.density has shape \(2,\).*1 rigid bodies",
    ),
    "Params of the wrong dimension": (
        lambda: jaxmps.simulate(
            *(lambda c: (c.scene, jaxmps.make_params(3, dt=1e-3), c.state))(
                jaxmps.scenes.hydrostatic(spacing=0.05)
            ),
            2,
            2,
        ),
        r"Params.gravity has shape \(3,\), expected \(2,\): the Scene is 2-D",
    ),
}


@pytest.mark.parametrize("what", list(BAD_INPUTS))
def test_bad_input_gets_a_clear_error(what):
    call, message = BAD_INPUTS[what]
    with pytest.raises(ValueError, match=message):
        call()
