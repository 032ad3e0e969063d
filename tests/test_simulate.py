"""`jaxmps.simulate`: vmap over Params equals a loop, no retrace when only Params
change, what is saved, `throw`, and the neighbour lists carried from step to step
(as `simulate` does, and as a loop of `step` does from `with_neighbour_lists`)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import small_tank

import jaxmps
from jaxmps._result import result_code


def test_vmap_over_params_equals_loop():
    scene, params, state = small_tank()
    viscosities = jnp.array([1e-6, 1e-3, 1e-2])
    batch = eqx.tree_at(lambda p: p.viscosity, params, viscosities)
    axes = eqx.tree_at(
        lambda p: p.viscosity,
        jax.tree.map(lambda _: None, params),
        0,
        is_leaf=lambda x: x is None,
    )

    def run(p):
        return jaxmps.simulate(scene, p, state, 5, 5, throw=False).state.position

    batched = jax.vmap(run, in_axes=(axes,))(batch)
    for i, nu in enumerate(viscosities):
        single = run(eqx.tree_at(lambda p: p.viscosity, params, nu))
        np.testing.assert_allclose(batched[i], single, rtol=0, atol=1e-12)


def test_no_retrace_when_only_params_change():
    scene, params, state = small_tank()
    traces = []

    @eqx.filter_jit
    def run(scene, params, state):
        traces.append(1)
        return jaxmps.simulate(scene, params, state, 2, 2, throw=False).state

    run(scene, params, state)
    run(scene, jaxmps.make_params(2, dt=1e-3, viscosity=2e-3), state)
    run(scene, jaxmps.make_params(2, dt=5e-4, density=998.0, beta=0.95), state)
    assert len(traces) == 1


def test_mass_and_walls_conserved_and_result_successful():
    scene, params, state = small_tank()
    tr = jaxmps.simulate(scene, params, state, 20, 10)
    assert tr.result == jaxmps.Result.successful
    walls = np.asarray(state.kind) != 0
    np.testing.assert_array_equal(tr.state.position[walls], state.position[walls])
    assert int(tr.state.active.sum()) == int(state.active.sum())
    assert tr.saved.position.shape == (2,) + state.position.shape


def test_throw_raises_with_message_and_false_returns_result():
    scene, params, state = small_tank(max_neighbours=4)
    with pytest.raises(Exception, match="max_neighbours"):
        jaxmps.simulate(scene, params, state, 2, 2, throw=True)
    tr = jaxmps.simulate(scene, params, state, 2, 2, throw=False)
    assert tr.result == jaxmps.Result.neighbour_overflow


def test_a_fixed_step_rollout_stops_at_its_first_failure():
    # dt 20 ms at l0 = 2 cm: the falling column passes the Courant limit in the
    # second step. The steps after it would have run on (the column falling
    # through the floor); the rollout keeps the failed state instead, in every
    # later save, and a batch member that fails does not stop the others.
    case = jaxmps.scenes.dam_break(spacing=0.02, dt=0.02)
    scene, params, state = case.scene, case.params, case.state
    tr = jaxmps.simulate(scene, params, state, 12, 2, throw=False)
    assert tr.result == jaxmps.Result.step_too_large
    failed_at = int(tr.state.step)
    assert 0 < failed_at < 12
    np.testing.assert_allclose(float(tr.state.time), failed_at * 0.02, rtol=1e-12)
    assert int(np.sum(tr.steps.accepted)) == failed_at
    last = tr.saved.position[-1]
    np.testing.assert_array_equal(last, tr.state.position)
    after = (failed_at + 1) // 2  # the first save taken entirely after it
    np.testing.assert_array_equal(
        tr.saved.position[after:],
        last[None].repeat(len(tr.saved.position) - after, axis=0),
    )
    assert int(tr.state.active.sum()) == int(state.active.sum())

    dts = jnp.asarray([0.02, 0.002], params.dt.dtype)
    batch = jax.vmap(
        lambda dt: jaxmps.simulate(
            scene, eqx.tree_at(lambda p: p.dt, params, dt), state, 12, 2, throw=False
        )
    )(dts)
    codes = np.asarray(result_code(batch.result))
    assert codes[0] == result_code(jaxmps.Result.step_too_large)
    assert codes[1] == result_code(jaxmps.Result.successful)
    np.testing.assert_allclose(
        batch.state.position[0], tr.state.position, rtol=0, atol=1e-12
    )
    assert int(batch.state.step[0]) == failed_at
    assert int(batch.state.step[1]) == 12


@pytest.mark.parametrize("solver", ["semi_implicit", "explicit"])
def test_carried_neighbour_lists_change_a_rollout_by_round_off_only(solver):
    # simulate carries the lists from search to search, at each step's start
    # and predicted positions (tests/test_neighbours.py checks when they are
    # used); a loop of `step` on a State without them searches twice per step.
    # The pressure solve is converged (rtol 1e-12): at the default tolerance two
    # solves that differ by round-off stop at different iterates, and the
    # positions then differ by the tolerance's share (3.5e-11 of the scale after
    # 40 steps on one host), not by round-off (4e-17 converged).
    solve = {"rtol": 1e-12} if solver == "semi_implicit" else {}
    case = jaxmps.scenes.dam_break(spacing=0.146 / 8, solver=solver, **solve)
    scene, params, state = case.scene, case.params, case.state
    assert scene.neighbour_skin == pytest.approx(0.3 * scene.spacing)
    n_steps = 40
    rollout = jaxmps.simulate(scene, params, state, n_steps, 10, throw=True)
    assert rollout.state.neighbours is None and rollout.saved.position.shape[0] == 4
    looped = state
    for _ in range(n_steps):
        looped, _ = jaxmps.step(scene, params, looped)
    assert looped.neighbours is None
    scale = float(jnp.max(jnp.abs(looped.position)))
    np.testing.assert_allclose(
        rollout.state.position, looped.position, rtol=0, atol=1e-11 * scale
    )
    np.testing.assert_allclose(
        rollout.state.pressure,
        looped.pressure,
        rtol=0,
        atol=1e-8 * float(jnp.max(looped.pressure)),
    )
    assert bool(jnp.any(looped.position != state.position))
    # A loop of `step` from `with_neighbour_lists` carries them as simulate does:
    # the same rollout, and the lists come out of each step for the next.
    carried = jaxmps.with_neighbour_lists(scene, state)
    for _ in range(n_steps):
        carried, _ = jaxmps.step(scene, params, carried)
        assert carried.neighbours is not None and bool(carried.neighbours.valid)
    np.testing.assert_allclose(
        rollout.state.position, carried.position, rtol=0, atol=1e-11 * scale
    )
    assert jaxmps.without_neighbour_lists(carried).neighbours is None
