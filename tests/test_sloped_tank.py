"""The sloped tank's three slope walls (seed 001 §3.3.2, Fig. 3.10): their number
density against the other walls', and that each runs."""

import numpy as np
import pytest

import jaxmps
from jaxmps import Kind, scenes


def _wall_density(case):
    """Mean number density, from wall and dummy neighbours only, of the wall
    particles on the slope and on the bottom, over n0."""
    kind = np.asarray(case.state.kind)
    x = np.asarray(case.state.position)
    r_e = case.scene.r_e
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    near = (d > 0) & (d < r_e) & (kind[None] != int(Kind.FLUID))
    n = np.where(near, r_e / np.where(d > 0, d, 1.0) - 1.0, 0.0).sum(axis=1)
    wall = kind == int(Kind.WALL)
    slope = wall & (x[:, 0] > 0.33) & (x[:, 1] > 0.05) & (x[:, 1] < 0.4)
    bottom = wall & (x[:, 1] < 0) & (x[:, 0] > 0.05) & (x[:, 0] < 0.25)
    return n[slope].mean() / case.scene.n0, n[bottom].mean() / case.scene.n0


def test_slope_walls_have_the_seeds_number_densities():
    """Type 2 (dummies normal to the slope) and the lattice staircase give the slope
    the bottom's number density; type 1 (dummies stacked vertically under a
    diagonal row) a denser slope (seed: "pushes harder"); measured 0.676 /
    0.676 / 0.841 of n0 against the bottom's 0.676 at l0 = 2 cm."""
    density = {
        wall: _wall_density(
            scenes.sloshing_tank(slope=1.5, spacing=0.02, slope_wall=wall)
        )
        for wall in ("staircase", "type1", "type2")
    }
    for wall in ("staircase", "type2"):
        slope, bottom = density[wall]
        assert abs(slope / bottom - 1) < 0.01
    slope, bottom = density["type1"]
    assert slope / bottom > 1.15


@pytest.mark.parametrize("wall", ["type1", "type2"])
def test_diagonal_slope_walls_hold_water_while_shaken(wall):
    """1 s of shaking at the first resonance from rest: the run completes, no
    fluid particle crosses the slope (more than half a spacing below it)."""
    case = scenes.sloshing_tank(
        slope=1.5, spacing=0.025, slope_wall=wall, settle=0.0, dt=2e-3
    )
    traj = jaxmps.simulate(case.scene, case.params, case.state, n_steps=500)
    assert traj.result == jaxmps.Result.successful
    x = np.asarray(traj.state.position)
    water = np.asarray(traj.state.kind) == int(Kind.FLUID)
    base, slope = case.config["bottom_width"], case.config["slope"]
    time = traj.state.time
    shift = float(case.scene.motion.law.displacement(case.params.motion, time))
    below = (
        x[water, 1]
        < (x[water, 0] - shift - base) / slope - 0.5 * case.config["spacing"]
    )
    assert not np.any(below)


def test_an_unknown_slope_wall_is_refused():
    with pytest.raises(ValueError, match="slope_wall='type3'.*staircase"):
        scenes.sloshing_tank(slope=1.5, spacing=0.05, slope_wall="type3")


def test_first_sloshing_mode_released_as_a_standing_wave():
    """`standing_wave(mode_number=1)` releases cos(pi x / L), the mode a shaken
    tank of that size resonates in: its linear period is the shaken tank's first
    resonance (two formulas, seed 001 eqs. 3.4-3.7), the water is the still
    tank's (the cosine's half wave adds none), and the mode probe reads the
    released amplitude, the seed's mode 2 (one wavelength) none of it."""
    length, depth, amplitude, l0 = 0.5, 0.2, 0.03, 0.01
    first = scenes.standing_wave(
        mode_number=1, tank_length=length, depth=depth, amplitude=amplitude
    )
    shaken = scenes.sloshing_tank(tank_length=length, depth=depth, spacing=l0)
    assert first.config["linear_period"] == pytest.approx(
        1 / shaken.config["resonances"][0], rel=1e-12
    )
    fluid = np.asarray(first.state.kind) == int(Kind.FLUID)
    assert fluid.sum() == round(length / l0) * round(depth / l0)
    probe = {p.name: p for p in first.probes}["mode"]
    assert float(probe(first.scene, first.state)) == pytest.approx(amplitude, rel=0.1)
    seed = scenes.standing_wave(tank_length=length, depth=depth, amplitude=amplitude)
    assert seed.config["mode_number"] == 2
    two = {p.name: p for p in seed.probes}["mode"]
    assert abs(float(two(first.scene, first.state))) < 0.1 * amplitude
    with pytest.raises(ValueError, match="mode_number"):
        scenes.standing_wave(mode_number=0)
