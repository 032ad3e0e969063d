"""3-D scenes: hydrostatic pressure and a quasi-2-D dam break against the 2-D one."""

import numpy as np
import pytest

import jaxmps


def test_hydrostatic_3d_bottom_pressure():
    """Coarse 3-D tank (8 layers deep): time-averaged pressure of the interior bottom
    row within 5 % of rho g (H - y), the weight of the water above (the surface
    particles carry the head of the water above them, `SemiImplicit.surface_head`).

    The floor's wall particles carry the water's weight too, also where the floor
    meets one side wall (edges) or two (corners): within 2 % of rho g (H - z)
    (measured 1.000-1.010). With zero-gradient dummies (`dummy_head=False`) they
    read 0.93-0.97, and the water, pushed towards the lower pressure, creeps into
    the corners: its lowest particle falls from l0/2 to 0.08 l0 above the floor in
    0.6 s (0.22 l0 with the hydrostatic dummies)."""
    l0, width, depth = 0.02, 0.12, 0.16
    case = jaxmps.scenes.hydrostatic(dim=3, spacing=l0, width=width, depth=depth)
    n = int(0.6 / float(case.params.dt)) // 20 * 20
    tr = jaxmps.simulate(case.scene, case.params, case.state, n, 20)
    half = tr.saved.time.shape[0] // 2
    p = np.asarray(tr.saved.pressure[half:]).mean(0)
    y = np.asarray(tr.saved.position[half:, :, -1]).mean(0)
    x0 = np.asarray(case.state.position)
    fluid = np.asarray(case.state.kind) == int(jaxmps.Kind.FLUID)
    inner = np.all((x0[:, :-1] > 1.5 * l0) & (x0[:, :-1] < width - 1.5 * l0), axis=1)
    bottom = fluid & inner & (x0[:, -1] < l0)
    ref = 1000.0 * 9.81 * (depth - y[bottom])
    assert p[bottom].mean() == pytest.approx(ref.mean(), rel=0.05)
    assert float(np.abs(np.asarray(tr.state.velocity)).max()) < 0.3

    wall = np.asarray(case.state.kind) == int(jaxmps.Kind.WALL)
    floor = wall & (x0[:, -1] < 0) & (x0[:, -1] > -l0)
    beside = np.sum((x0[:, :-1] < 0) | (x0[:, :-1] > width), axis=1)
    assert set(beside[floor]) == {0, 1, 2}  # floor, edges and corners
    weight = 1000.0 * 9.81 * (depth - x0[floor, -1])
    np.testing.assert_allclose(p[floor] / weight, 1.0, atol=0.02)
    lowest = np.asarray(tr.saved.position[:, fluid, -1]).min()
    assert lowest > 0.15 * l0


def _front(dim):
    case = jaxmps.scenes.dam_break(
        dim=dim,
        spacing=0.0146,
        tank_length=0.438,
        tank_height=0.3504,
        tank_width=0.0438,
    )
    obs = jaxmps.scenes.observe_probes(case.probes)
    n = int(0.13 / float(case.params.dt)) // 10 * 10
    tr = jaxmps.simulate(case.scene, case.params, case.state, n, 10, obs)
    a = case.config["column_width"]
    t = np.asarray(tr.saved["time"]) * np.sqrt(2 * 9.81 / a)
    final = tr.state
    assert int(final.active.sum()) == int(case.state.active.sum())
    walls = np.asarray(case.state.kind) != int(jaxmps.Kind.FLUID)
    np.testing.assert_array_equal(final.position[walls], case.state.position[walls])
    return t, np.asarray(tr.saved["front"]) / a


@pytest.mark.slow
def test_quasi_2d_dam_break_in_3d_matches_2d():
    """A 3-D column three particles wide between two walls must collapse like the 2-D
    column (measured within 2 %)."""
    t2, z2 = _front(2)
    t3, z3 = _front(3)
    for T in (1.0, 1.4):
        assert np.interp(T, t3, z3) == pytest.approx(np.interp(T, t2, z2), rel=0.05)
    assert np.interp(1.4, t3, z3) > 1.5
