"""Gradients of rollouts: jax.grad of short rollouts against central finite
differences (float64) for every Params field of every component that exists,
the same gradient under every checkpoint setting, and finite gradients with
padded and coincident particles.

Discrete decisions carry no gradient and are documented here:
- beta (free-surface threshold): the flags are a step function of beta, so the
  exact derivative is zero almost everywhere (and jax.grad returns exactly 0).
- inflow spawning: *when* a column spawns is discrete; between spawns the gradient
  w.r.t. the inflow velocity flows through the moving boundary. The rollouts below
  stay between two spawns.
- stick/slip (rigid friction): whether a body sticks is a step function of mu_s,
  so d/d(mu_s) is exactly zero; mu_k has a gradient while the body slides (the
  removed speed mu_k N dt / M is linear in it) and none while it sticks
  (`Coulomb(smoothing=...)` gives one in both regimes). The sliding block's
  gradients (mu_k, gravity, mu_s exactly zero) are checked against differences
  and the sliding law in test_contact.py.
- kinks: the negative-pressure clamp max(p, 0), the minimum-pressure shift and the
  collision guard are continuous but not smooth. A finite-difference step can
  straddle one (seen for inflow.velocity at h = 1e-4 |x|: forward and backward
  differences 44.62 vs 44.74, AD 44.74); steps of 1e-6 |x| do not, and agree with
  AD to ~1e-9. Gradients are those of the branch the rollout took.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import small_tank

import jaxmps
from jaxmps.calibration._fields import get_field, set_field
from jaxmps.fluid import Harmonic, HarmonicParams, PrescribedMotion


def _setup():
    scene, params, state = small_tank(
        width=0.06,
        depth=0.06,
        solver=jaxmps.SemiImplicit(rtol=1e-13, max_iterations=5000),
    )
    params = eqx.tree_at(lambda p: p.viscosity, params, jnp.asarray(1e-2))
    # A small initial motion so that the rollout is not trivially at rest.
    fluid = (state.kind == 0)[:, None]
    swirl = jnp.stack([-(state.position[:, 1] - 0.03), state.position[:, 0] - 0.03], -1)
    state = eqx.tree_at(lambda s: s.velocity, state, jnp.where(fluid, 0.5 * swirl, 0.0))
    return scene, params, state


def _field_loss(value, field, scene, params, state, checkpoint=True):
    p = eqx.tree_at(lambda p: getattr(p, field), params, value)
    final = jaxmps.simulate(
        scene, p, state, 6, 3, throw=False, checkpoint=checkpoint
    ).state
    fluid = state.kind == 0
    return jnp.sum(jnp.where(fluid, final.pressure, 0.0)) * 1e-3 + jnp.sum(
        jnp.where(fluid[:, None], final.position, 0.0) ** 2
    )


@pytest.mark.parametrize("field", ["viscosity", "density"])
def test_rollout_gradient_matches_central_differences(field):
    scene, params, state = _setup()
    x0 = getattr(params, field)
    g = jax.grad(_field_loss)(x0, field, scene, params, state)
    h = 1e-4 * x0
    fd = (
        _field_loss(x0 + h, field, scene, params, state)
        - _field_loss(x0 - h, field, scene, params, state)
    ) / (2 * h)
    assert np.isfinite(g) and abs(float(fd)) > 0
    assert float(g) == pytest.approx(float(fd), rel=1e-4)


@pytest.mark.slow
def test_checkpoint_settings_give_the_same_gradient():
    """Rematerialising blocks, blocks and steps, or nothing changes only memory and
    time: the same value and gradient to round-off (float64)."""
    scene, params, state = _setup()
    x0 = params.viscosity
    out = {
        c: jax.value_and_grad(_field_loss)(x0, "viscosity", scene, params, state, c)
        for c in (True, "steps", False)
    }
    for c in ("steps", False):
        assert float(out[c][0]) == pytest.approx(float(out[True][0]), rel=1e-12)
        assert float(out[c][1]) == pytest.approx(float(out[True][1]), rel=1e-9)


def test_an_unknown_checkpoint_setting_is_refused():
    scene, params, state = _setup()
    # A ValueError naming the setting; under the test suite's runtime type checks
    # (beartype through jaxtyping) the annotation refuses it first, a TypeError.
    with pytest.raises((ValueError, TypeError), match="checkpoint"):
        jaxmps.simulate(scene, params, state, 6, 3, checkpoint="step")
    with pytest.raises(ValueError, match="checkpoint must be True, False or 'steps'"):
        jaxmps._simulate._check_checkpoint("step")


def test_gradients_finite_with_padding_and_coincident_particles():
    scene, params, state = small_tank(capacity=None)
    # Put two fluid particles on top of each other.
    state = eqx.tree_at(
        lambda s: s.position, state, state.position.at[1].set(state.position[0])
    )

    def loss(nu):
        p = eqx.tree_at(lambda p: p.viscosity, params, nu)
        return jnp.sum(
            jaxmps.simulate(scene, p, state, 2, 2, throw=False).state.position
        )

    assert np.isfinite(jax.grad(loss)(jnp.asarray(1e-3)))


def _swirl(state, centre=0.03):
    fluid = (state.kind == 0)[:, None]
    x = state.position
    swirl = jnp.stack([-(x[:, 1] - centre), x[:, 0] - centre], -1)
    return eqx.tree_at(lambda s: s.velocity, state, jnp.where(fluid, 0.5 * swirl, 0.0))


def _tank(solver):
    # The explicit solver gets the E-MPS scheme (weight, gradient) of its preset.
    scene, params, state = small_tank(width=0.06, depth=0.06, solver=solver)
    params = set_field(params, "viscosity", jnp.asarray(1e-2))
    if isinstance(solver, jaxmps.Explicit):
        params = set_field(params, "dt", jnp.asarray(4e-4))  # c dt / l0 = 0.4
    return scene, params, _swirl(state)


def _moving_tank():
    scene, params, state = _tank(jaxmps.SemiImplicit(rtol=1e-13, max_iterations=5000))
    walls = tuple(int(i) for i in np.nonzero(np.asarray(state.kind) != 0)[0])
    motion = PrescribedMotion(particles=walls, axis=(1.0, 0.0), law=Harmonic())
    scene = eqx.tree_at(lambda s: s.motion, scene, motion, is_leaf=lambda x: x is None)
    params = eqx.tree_at(
        lambda p: p.motion,
        params,
        HarmonicParams(amplitude=0.003, frequency=3.0),
        is_leaf=lambda x: x is None,
    )
    return scene, params, state


def _flume():
    # Fixed steps: adaptive ones would follow the inflow's speed, which finite
    # differences see and the gradient does not (the dt is a constant to it).
    settings = dict(
        spacing=0.0075, bed_length=0.09, rtol=1e-13, max_iterations=5000, viscosity=1e-2
    )
    dt = float(jaxmps.scenes.flume(**settings).params.dt)
    case = jaxmps.scenes.flume(**settings, dt=dt)
    return case.scene, case.params, case.state


def _floating(**settings):
    case = jaxmps.scenes.floating_box(
        spacing=0.02,
        tank_length=0.4,
        depth=0.1,
        box_width=0.1,
        box_height=0.06,
        rtol=1e-13,
        max_iterations=5000,
        viscosity=1e-2,
        **settings,
    )
    return case.scene, case.params, case.state


def _heeled():
    # A box with a given centre of gravity and gyration, heeled so that both act.
    return _floating(heel=5.0, centre_of_gravity=0.02, gyration=0.03)


SEMI = jaxmps.SemiImplicit(rtol=1e-13, max_iterations=5000)


CASES = {
    "floating": _floating,
    "heeled": _heeled,
    "semi": lambda: _tank(SEMI),
    "explicit": lambda: _tank(jaxmps.Explicit()),
    "moving": _moving_tank,
    "flume": _flume,
}


FIELDS = [
    ("semi", "viscosity", 1e-4),
    ("semi", "density"),
    ("semi", "gravity"),
    ("semi", "dt", 1e-4),
    ("explicit", "sound_speed"),
    ("explicit", "viscosity"),
    ("explicit", "density"),
    ("explicit", "gravity"),
    ("explicit", "dt"),
    ("moving", "motion.amplitude"),
    ("moving", "motion.frequency"),
    ("flume", "inflow.velocity"),
    ("floating", "rigid.density"),
    ("floating", "density"),
    ("heeled", "rigid.centre_of_mass"),
    ("heeled", "rigid.gyration"),
]
# Cases whose gradient programs take about a minute or more to compile (the
# flume's inflow and outflow, the bodies' stages): the slow tier.
SLOW_CASES = ("flume", "floating", "heeled")


def _loss(scene, params, state, n_steps=6):
    final = jaxmps.simulate(scene, params, state, n_steps, 3, throw=False).state
    fluid = final.active & ((final.kind == 0) | (final.kind == int(jaxmps.Kind.RIGID)))
    return jnp.sum(jnp.where(fluid, final.pressure, 0.0)) * 1e-3 + jnp.sum(
        jnp.where(fluid[:, None], final.position, 0.0) ** 2
    )


# Choice of the difference step: 1e-6 |x| by default, below the kinks above. Where
# the loss varies little over such a step its round-off decides instead: the pressure
# solve leaves ~1e-12 of it (rtol 1e-13 on sums of ~1e3 Pa), which over a step of
# 1e-6 dt = 1e-9 s is noise of ~1e-3 of the derivative (semi-implicit dt: forward and
# backward differences -0.10279 and -0.10215, AD -0.10259). Those cases take 1e-4 |x|,
# where forward and backward differences differ only by the curvature (~1e-3) and the
# central one meets AD to 1e-8 (dt) and 1e-6 (mu_k). The semi-implicit viscosity
# (nu = 1e-6, a step of 1e-12 m^2/s) is such a case on some hosts: on an AMD EPYC
# host central differences at 1e-6 / 1e-5 / 1e-4 |x| read -0.1215649 / -0.1215367 /
# -0.1215388 against AD -0.1215387 (2e-4, 2e-5, 2e-7).
@pytest.mark.parametrize(
    "case_name, field, step",
    [
        pytest.param(*f, marks=pytest.mark.slow) if f[0] in SLOW_CASES else f
        for f in ((*f, 1e-6) if len(f) == 2 else f for f in FIELDS)
    ],
)
def test_gradient_matches_central_differences(case_name, field, step):
    scene, params, state = CASES[case_name]()
    x0 = get_field(params, field)
    direction = jnp.ones_like(x0) / np.sqrt(x0.size)

    def f(t):
        return _loss(scene, set_field(params, field, x0 + t * direction), state)

    g = jax.grad(lambda p: _loss(scene, p, state))(params)
    analytic = float(jnp.vdot(get_field(g, field), direction))
    h = step * float(jnp.max(jnp.abs(x0)))
    fd = (f(h) - f(-h)) / (2 * h)
    assert np.isfinite(analytic) and abs(float(fd)) > 1e-12
    assert analytic == pytest.approx(float(fd), rel=1e-4)


def test_beta_gradient_is_exactly_zero_and_so_is_the_difference():
    scene, params, state = _tank(SEMI)
    g = jax.grad(lambda p: _loss(scene, p, state))(params)
    assert float(g.beta) == 0.0
    up = _loss(scene, set_field(params, "beta", params.beta + 1e-6), state)
    down = _loss(scene, set_field(params, "beta", params.beta - 1e-6), state)
    assert float(up) == float(down)


def _field_loss_over_time(value, field, scene, params, state, autodiff):
    """`_field_loss`, with the saves at times (a while loop per save)."""
    p = eqx.tree_at(lambda p: getattr(p, field), params, value)
    final = jaxmps.simulate(
        scene, p, state, times=[0.003, 0.006], throw=False, autodiff=autodiff
    ).state
    fluid = state.kind == 0
    return jnp.sum(jnp.where(fluid, final.pressure, 0.0)) * 1e-3 + jnp.sum(
        jnp.where(fluid[:, None], final.position, 0.0) ** 2
    )


@pytest.mark.slow
def test_forward_mode_equals_reverse_mode_and_differences():
    """`autodiff="forward"`: jax.jacfwd of an adaptive rollout saved at times (a
    plain while loop per save) equals jax.grad of the checkpointed one and central
    differences; the values are the same run's (to round-off: the two programs
    are compiled apart). The default refuses forward mode
    by name; a fixed-step rollout takes either mode as it is."""
    scene, params, state = _setup()
    adaptive = eqx.tree_at(
        lambda s: s.time_step, scene, jaxmps.Adaptive(), is_leaf=lambda x: x is None
    )
    x0 = params.viscosity
    args = ("viscosity", adaptive, params, state)

    def both(v):
        value = _field_loss_over_time(v, *args, "forward")
        return value, value

    jac, value_f = jax.jacfwd(both, has_aux=True)(x0)
    value_r, rev = jax.value_and_grad(_field_loss_over_time)(x0, *args, "reverse")
    assert float(value_f) == pytest.approx(float(value_r), rel=1e-13)
    h = 1e-4 * x0
    fd = (
        _field_loss_over_time(x0 + h, *args, "reverse")
        - _field_loss_over_time(x0 - h, *args, "reverse")
    ) / (2 * h)
    assert abs(float(fd)) > 0
    assert float(jac) == pytest.approx(float(rev), rel=1e-9)
    assert float(rev) == pytest.approx(float(fd), rel=1e-4)
    # Fixed steps (nested scans): jax.jacfwd, a vmap of JVPs, through the pressure
    # solve, whose iteration count must stay the primal's (unbatched).
    fixed = ("viscosity", scene, params, state)
    assert float(jax.jacfwd(_field_loss)(x0, *fixed)) == pytest.approx(
        float(jax.grad(_field_loss)(x0, *fixed)), rel=1e-9
    )


def test_autodiff_settings_are_checked():
    """An unknown mode is refused; forward mode through a rollout set up for
    reverse mode says which setting to change (JAX's own error named a
    custom_vjp)."""
    scene, params, state = _setup()
    with pytest.raises((ValueError, TypeError), match="autodiff"):
        jaxmps.simulate(scene, params, state, 6, 3, autodiff="backward")
    adaptive = eqx.tree_at(
        lambda s: s.time_step, scene, jaxmps.Adaptive(), is_leaf=lambda x: x is None
    )
    args = ("viscosity", adaptive, params, state, "reverse")
    with pytest.raises(TypeError, match="autodiff='forward'"):
        jax.jacfwd(_field_loss_over_time)(params.viscosity, *args)


def _observe_time(scene, state):
    return state.time


@pytest.mark.slow
@pytest.mark.parametrize(
    "build, field",
    [
        (lambda: jaxmps.scenes.dam_break(spacing=0.02, solver="explicit"), "viscosity"),
        (lambda: jaxmps.scenes.floating_box(spacing=0.02), "viscosity"),
        (lambda: jaxmps.scenes.elastic_cantilever(), "elastic.youngs_modulus"),
        (lambda: jaxmps.scenes.granular_collapse(), "grains.friction"),
    ],
    ids=["explicit", "rigid", "elastic", "grains"],
)
def test_forward_mode_through_every_kind_of_stage(build, field):
    """A JVP along one field of a timed rollout (`autodiff="forward"`) equals the
    reverse-mode gradient's, with bodies of each model (measured: 3e-16 / 1e-7 /
    7e-10 / 4e-14; porous regions 7e-9, 3-D 3e-8, the tsunami's inflow 6e-8)."""
    case = build()
    x0 = jnp.asarray(get_field(case.params, field))
    times = jnp.arange(1, 4) * 10 * jnp.min(jnp.asarray(case.params.dt))

    def loss(v, autodiff):
        p = set_field(case.params, field, v)
        out = jaxmps.simulate(
            case.scene,
            p,
            case.state,
            times=times,
            observe=_observe_time,
            throw=False,
            autodiff=autodiff,
        )
        moving = out.state.active[:, None]
        return jnp.sum(jnp.where(moving, out.state.position * out.state.velocity, 0))

    forward = jax.jvp(lambda v: loss(v, "forward"), (x0,), (jnp.ones_like(x0),))[1]
    reverse = jax.grad(loss)(x0, "reverse")
    assert abs(float(forward)) > 0
    assert float(forward) == pytest.approx(float(jnp.sum(reverse)), rel=1e-6)
