"""One step: jit equals no jit, hydrostatic pressure at rest, the run-time result
codes (Courant limit, a particle out of the domain, non-finite state) and
clear errors for bad input."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import small_tank

import jaxmps


# Slow tier: without jit every primitive compiles on its own (456 of them, ~22 s
# alone, 44 s beside the other worker), whatever the tank's size.
@pytest.mark.slow
def test_jit_equals_no_jit():
    # The pressure solve converged (rtol 1e-12): at the default tolerance the two
    # programs' round-off stops CG at different iterates, and the positions differ
    # by the tolerance's share (5e-12 m on one host), not by round-off.
    scene, params, state = small_tank()
    scene = eqx.tree_at(
        lambda s: s.solver.rtol, scene, 1e-12, is_leaf=lambda x: x is None
    )
    jitted, _ = jaxmps.step(scene, params, state)
    with jax.disable_jit():
        plain, _ = jaxmps.step(scene, params, state)
    np.testing.assert_allclose(jitted.position, plain.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(jitted.pressure, plain.pressure, rtol=1e-7, atol=1e-6)


def test_hydrostatic_pressure_within_5_percent():
    """Seed 000 §10.2 #4: P = rho g (H - y) after settling (2-D, standard scheme),
    time-averaged over the last half of 1 s."""
    case = jaxmps.scenes.hydrostatic(spacing=0.01, width=0.2, depth=0.2)
    obs = jaxmps.scenes.observe_probes(case.probes)
    tr = jaxmps.simulate(case.scene, case.params, case.state, 1000, 20, obs)
    p = {k: np.asarray(v)[25:].mean() for k, v in tr.saved.items()}
    rho_g = 1000.0 * 9.81
    # Bottom probe: mean height of the probed particles is y = l0/2 -> depth H - l0/2.
    assert p["pressure_bottom"] == pytest.approx(rho_g * (0.2 - 0.005), rel=0.05)
    # Mid-depth probe (y = 0.1): the surface particles carry the head of the water
    # above them (`SemiImplicit.surface_head`), so the pressure is the weight of
    # the water above, rho g (H - y). (With the seed's P = 0 there the effective
    # surface lay l0/2 lower, at 0.195 m.)
    assert p["pressure_middle"] == pytest.approx(rho_g * (0.2 - 0.1), rel=0.05)
    # Spurious currents stay small.
    assert float(jnp.abs(tr.state.velocity).max()) < 0.2


def test_time_step_beyond_courant_limit_is_reported():
    scene, params, state = small_tank()
    fast = eqx.tree_at(lambda s: s.velocity, state, state.velocity.at[0].set(100.0))
    tr = jaxmps.simulate(scene, params, fast, 1, 1, throw=False)
    assert tr.result == jaxmps.Result.step_too_large


def test_particle_leaving_domain_is_reported():
    scene, params, state = small_tank()
    out = eqx.tree_at(
        lambda s: s.position, state, state.position.at[0].set(jnp.array([5.0, 5.0]))
    )
    tr = jaxmps.simulate(scene, params, out, 1, 1, throw=False)
    assert tr.result == jaxmps.Result.left_domain


def test_nonfinite_state_is_reported():
    scene, params, state = small_tank()
    bad = eqx.tree_at(lambda s: s.velocity, state, state.velocity.at[3].set(jnp.nan))
    # A concrete initial state is refused before anything runs ...
    with pytest.raises(ValueError, match=r"State.velocity is not finite .* \[3\]"):
        jaxmps.simulate(scene, params, bad, 1, 1, throw=False)
    # ... and inside a user's jit (traced state) the run-time result code applies.
    run = jax.jit(lambda s: jaxmps.simulate(scene, params, s, 1, 1, throw=False))
    assert run(bad).result != jaxmps.Result.successful


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="no particles"):
        jaxmps.make_scene(np.zeros((0, 2)), 0.01, ([0, 0], [1, 1]))
    with pytest.raises(ValueError, match="Unknown scene"):
        jaxmps.scenes.build("dambreak")
    with pytest.raises(ValueError, match="Valid parameters"):
        jaxmps.scenes.dam_break(colum_width=0.1)
    with pytest.raises(ValueError, match="solver"):
        jaxmps.scenes.dam_break(solver="implicit")
    with pytest.raises(ValueError, match="dt"):
        jaxmps.make_params(2, dt=-1.0)
    scene, params, state = small_tank()
    with pytest.raises(ValueError, match="multiple"):
        jaxmps.simulate(scene, params, state, 5, 2)
    other, _, _ = small_tank(width=0.05)
    with pytest.raises(ValueError, match="Scene expects"):
        jaxmps.simulate(other, params, state, 2, 2)


def test_collision_guard_closes_the_holes_of_a_3d_wall():
    """The pair guard alone (0.5 l0) lets a fluid particle through the middle of a
    3-D wall's lattice cell (l0 / sqrt(2) from its corners, and so through every
    dummy layer behind it); the wall-plane guard reverses its approach with the
    restitution, relative to a moving wall, once within 0.5 l0 of the plane. It
    does not act twice where the pair guard has acted, nor on a particle farther
    off or moving away."""
    from jaxmps.fluid import CollisionGuard
    from jaxmps.geometry import block
    from jaxmps.neighbours import build
    from jaxmps.operators import make_pairs

    l0 = 1.0
    solid = block([0.0, 0.0, -3 * l0], [12 * l0, 12 * l0, 0.0], l0)  # centres -0.5 ..
    kind = np.where(solid[:, 2] > -l0, int(jaxmps.Kind.WALL), int(jaxmps.Kind.DUMMY))
    plane = -0.5 * l0
    fluid = np.array(
        [
            [3.0, 3.0, plane + 0.3],  # above a cell's middle, 0.3 l0 off the plane
            [8.5, 3.5, plane + 0.3],  # above a wall particle, 0.3 l0 off
            [3.0, 8.0, plane + 0.8],  # above a cell's middle, 0.8 l0 off
            [8.0, 8.0, plane + 0.3],  # above a cell's middle, moving away
        ]
    )
    x = np.concatenate([solid, fluid])
    kind = np.concatenate([kind, np.zeros(len(fluid), int)]).astype(np.int32)
    domain = (np.array([-3.0, -3.0, -6.0]), np.array([15.0, 15.0, 6.0]))
    scene = jaxmps.make_scene(x, l0, domain)
    x = jnp.asarray(x)
    active = jnp.ones(len(x), bool)
    nbrs = build(scene.grid, x, active, scene.max_neighbours, scene.r_e)
    pairs = make_pairs(nbrs.index, x, scene.weight, scene.r_e)
    u = np.zeros_like(np.asarray(x))
    u[-4:] = [[0.2, 0.0, -1.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]
    guard, pairs_only = CollisionGuard(), CollisionGuard(wall_plane=False)
    disc, kind = scene.discretisation, jnp.asarray(kind)
    before = pairs_only(disc, jnp.asarray(u), kind, active, pairs)
    after = guard(disc, jnp.asarray(u), kind, active, pairs)
    np.testing.assert_allclose(before[-4], [0.2, 0.0, -1.0])  # through the hole
    np.testing.assert_allclose(after[-4], [0.2, 0.0, 0.2], atol=1e-12)  # e = 0.2
    np.testing.assert_allclose(before[-3], [0.0, 0.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(after[-3], before[-3], atol=1e-12)  # not twice
    np.testing.assert_allclose(after[-2:], u[-2:])
    # A wall moving down at 0.5 m/s: the approach is 0.5 m/s, reversed to 0.1.
    u[: len(solid), 2] = -0.5
    after = guard(disc, jnp.asarray(u), kind, active, pairs)
    np.testing.assert_allclose(after[-4], [0.2, 0.0, -0.4], atol=1e-12)
