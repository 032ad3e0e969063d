import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import small_tank

import jaxmps


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


def _loss(value, field, scene, params, state, checkpoint=True):
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
    g = jax.grad(_loss)(x0, field, scene, params, state)
    h = 1e-4 * x0
    fd = (
        _loss(x0 + h, field, scene, params, state)
        - _loss(x0 - h, field, scene, params, state)
    ) / (2 * h)
    assert np.isfinite(g) and abs(float(fd)) > 0
    assert float(g) == pytest.approx(float(fd), rel=1e-4)


def test_checkpoint_settings_give_the_same_gradient():
    """Rematerialising blocks, blocks and steps, or nothing changes only memory and
    time: the same value and gradient to round-off (float64)."""
    scene, params, state = _setup()
    x0 = params.viscosity
    out = {
        c: jax.value_and_grad(_loss)(x0, "viscosity", scene, params, state, c)
        for c in (True, "steps", False)
    }
    for c in ("steps", False):
        assert float(out[c][0]) == pytest.approx(float(out[True][0]), rel=1e-12)
        assert float(out[c][1]) == pytest.approx(float(out[True][1]), rel=1e-9)
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
