"""Probes read what they name wherever their point falls on the lattice."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps


def _water_level(case):
    return next(p for p in case.probes if p.name == "water_level")


@pytest.mark.parametrize(
    "settings",
    [
        dict(spacing=0.01, width=1.0, depth=0.03),  # 100 columns: the gauge midway
        dict(spacing=0.02, width=0.5, depth=0.04),  # 25 columns: on the middle one
        dict(spacing=0.02, width=0.6, depth=0.2),
        dict(spacing=0.025, width=0.2, depth=0.2, dim=3),
    ],
)
def test_the_water_level_reads_the_depth_between_columns_and_on_one(settings):
    case = jaxmps.scenes.hydrostatic(**settings)
    probe = _water_level(case)
    depth, l0 = settings["depth"], settings["spacing"]
    assert float(probe(case.scene, case.state)) == pytest.approx(depth, abs=1e-6)
    # The columns sway by a fifth of a spacing (each its own way, less than the
    # quarter the window allows): the highest particle near the gauge is still
    # in the window.
    state = case.state
    fluid = np.asarray(state.kind) == int(jaxmps.Kind.FLUID)
    x = np.asarray(state.position[:, 0])
    column = np.rint((x - x[fluid].min()) / l0).astype(int)
    for sign in (-1.0, 1.0):
        sway = np.where(fluid, sign * 0.2 * l0 * (-1.0) ** column, 0.0)
        moved = state.position.at[:, 0].add(jnp.asarray(sway, state.position.dtype))
        swayed = dataclasses.replace(state, position=moved)
        assert float(probe(case.scene, swayed)) == pytest.approx(depth, abs=1e-6)
    # A dry tank reads 0.
    dry = dataclasses.replace(state, active=state.active & ~jnp.asarray(fluid))
    assert float(probe(case.scene, dry)) == 0.0
