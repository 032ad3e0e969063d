"""Friction on elastic bodies (seed 000 §2.6: it acts on the surface particles in
contact and the body's stresses carry it inward): an elastic block on a tilted
floor against Coulomb's law, the gradient through the kinetic coefficient, and
the refusals."""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps.bodies import Coulomb, SubmergedWeight

G = 9.81
TIMES = np.arange(0.02, 0.401, 0.02)


def _slide(angle, mu, **overrides):
    """The block's mean x over TIMES and its acceleration fitted from 0.1 s on."""
    case = jaxmps.scenes.friction_tilt(
        body="elastic", angle=angle, mu_static=mu, settle=0.2, **overrides
    )
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=TIMES,
        observe=jaxmps.scenes.observe_probes(case.probes),
    )
    x = np.asarray(out.saved["block_x"])
    assert out.result == jaxmps.Result.successful
    late = TIMES >= 0.1
    basis = np.stack([np.ones(late.sum()), TIMES[late], TIMES[late] ** 2 / 2], 1)
    accel = np.linalg.lstsq(basis, x[late], rcond=None)[0][2]
    return x, float(accel)


def test_an_elastic_block_on_a_tilted_floor_sticks_or_slides_as_coulomb_says():
    """A 1 m elastic block (E = 1e6 Pa, l0 = 0.1 m, pushed by the floor) at rest
    on a floor under gravity tilted by 35 degrees: frictionless it slides at
    g sin(35); with mu = 0.3 and 0.5 the floor's friction (g sin - a per unit
    mass) lies at or just below mu g cos (the law's bound: mu N while it slides;
    the contacting particles stick and slip in turn near the onset; measured
    1.00 and 0.97 of it). Tilted by 15 degrees with mu = 0.5 it stays: its mean
    sways out and back (the sudden tilt shears and bends it, undamped), where a
    slide would not turn back."""
    theta = math.radians(35)
    _, free = _slide(35, 0.0)
    assert free == pytest.approx(G * math.sin(theta), rel=1e-3)
    for mu in (0.3, 0.5):
        _, accel = _slide(35, mu)
        friction = (G * math.sin(theta) - accel) / (mu * G * math.cos(theta))
        assert 0.9 < friction < 1.01, (mu, friction)
    x, _ = _slide(15, 0.5)
    # measured: out to 0.86 cm at 0.16 s, back to 0.16 cm at 0.4 s
    assert np.max(np.abs(x - x[0])) < 0.02
    assert x[-1] < np.max(x) - 0.003


@pytest.mark.long
def test_the_slide_has_the_gradient_of_finite_differences_in_mu_kinetic():
    """d(block x after 0.1 s on a 45 degree floor)/d mu_kinetic by reverse mode
    against central differences of the same rollout, within 1e-4."""
    jax.config.update("jax_enable_x64", True)
    case = jaxmps.scenes.friction_tilt(
        body="elastic", angle=45, mu_static=0.5, settle=0.1, dt=5e-4
    )
    probe = case.probes[0]

    def x_end(mu):
        e = dataclasses.replace(case.params.elastic, mu_kinetic=mu)
        params = dataclasses.replace(case.params, elastic=e)
        out = jaxmps.simulate(
            case.scene,
            params,
            case.state,
            200,
            200,
            observe=lambda scene, s: probe(scene, s),
        )
        return out.saved[-1]

    mu = jnp.asarray([0.5])
    ad = float(jax.grad(lambda m: x_end(m))(mu)[0])
    # measured: FD -0.013709 / -0.013673 / -0.013648 / -0.0136497 at h = 1e-3 /
    # 3e-4 / 1e-4 / 3e-5 (some particles switch between stick and slip within
    # the wider steps), reverse mode -0.0136497
    h = 3e-5
    fd = float((x_end(mu + h) - x_end(mu - h)) / (2 * h))
    assert ad < 0  # more friction, less slide
    assert ad == pytest.approx(fd, rel=1e-4)


def test_elastic_friction_settings_are_refused_with_the_setting_named():
    """A friction law without mu_static, coefficients without a law, a negative
    coefficient, a whole body's normal force (SubmergedWeight), an unknown
    contact model, a dry-only elastic tilt in water and an unknown body model;
    and which contact a body gets by default."""
    case = jaxmps.scenes.block_impact(body="elastic", dt=1e-4, t_end=0.01)
    scene = dataclasses.replace(case.scene, elastic=None)
    body = np.where(np.asarray(case.state.elastic.index) >= 0, 0, -1)
    index = np.asarray(case.state.elastic.index)
    ids = -np.ones(case.scene.capacity, int)
    ids[index] = body
    plain = dataclasses.replace(
        case.state,
        elastic=None,
        kind=case.state.kind.at[index].set(int(jaxmps.Kind.FLUID)),
    )
    params = dataclasses.replace(case.params, elastic=None)
    common = dict(youngs_modulus=1e6, poisson_ratio=0.3, density=1000.0)

    def build(**kw):
        return jaxmps.add_elastic_bodies(scene, params, plain, ids, **common, **kw)

    with pytest.raises(ValueError, match="mu_static"):
        build(friction=Coulomb())
    with pytest.raises(ValueError, match="friction=jaxmps.bodies.Coulomb"):
        build(mu_static=0.5)
    with pytest.raises(ValueError, match=">= 0"):
        build(friction=Coulomb(), mu_static=0.5, mu_kinetic=-0.1)
    with pytest.raises(ValueError, match="SubmergedWeight"):
        build(friction=Coulomb(normal=SubmergedWeight()), mu_static=0.5)
    with pytest.raises(ValueError, match="ElasticBodies.contact must be"):
        build(contact="sticky")
    # dry among walls: the contact push; with water: through the pressure
    assert build()[0].elastic.contact == "push"
    assert build(contact="pressure")[0].elastic.contact == "pressure"
    assert jaxmps.scenes.elastic_gate().scene.elastic.contact == "pressure"
    built = build(friction=Coulomb(), mu_static=[0.4], mu_kinetic=0.3)
    assert np.allclose(built[1].elastic.mu_static, 0.4)
    assert np.allclose(built[1].elastic.mu_kinetic, 0.3)
    # a Params without the coefficients is refused by the scene's own check
    bare = dataclasses.replace(
        built[1],
        elastic=dataclasses.replace(built[1].elastic, mu_static=None),
    )
    with pytest.raises(ValueError, match=r"Params.elastic.mu_static is None"):
        jaxmps.simulate(built[0], bare, built[2], 1, 1)
    with pytest.raises(ValueError, match="water_depth"):
        jaxmps.scenes.friction_tilt(body="elastic", water_depth=1.5, settle=0)
    with pytest.raises(ValueError, match="body='foam'"):
        jaxmps.scenes.friction_tilt(body="foam")
