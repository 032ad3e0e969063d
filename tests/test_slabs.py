"""One explicit run split over devices by slabs with a halo (`simulate_slabs`):
the one-device run's values to round-off with particles crossing the cuts, a
halo too narrow for the step's reach visibly wrong, adaptive steps chosen over
all slabs, a slab that overflows stopping with the last good state, and what
bad input gets. Several CPU devices need XLA_FLAGS before JAX starts, so those
checks run in subprocesses."""

import json
import textwrap

import numpy as np
import pytest
from helpers import python_with_devices

import jaxmps

# A dam break long enough for four slabs wider than the halo (l0 = 1 cm).
_CASE = """
import json, jax, numpy as np, jaxmps
def case(dt=None):
    first = jaxmps.scenes.dam_break(solver="explicit", spacing=0.01,
                                    column_width=0.4, tank_length=1.6)
    return jaxmps.scenes.dam_break(solver="explicit", spacing=0.01,
                                   column_width=0.4, tank_length=1.6,
                                   dt=float(first.params.dt) if dt is None else dt)
def apart(a, b, active):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))[np.asarray(active)]))
"""


def _python(code: str, devices: int, timeout: float = 600):
    """Run `code` after `_CASE` in a fresh float64 interpreter with `devices` CPU
    devices; the JSON it prints last."""
    out = python_with_devices(_CASE + textwrap.dedent(code), devices, timeout)
    return json.loads(out.strip().splitlines()[-1])


def test_four_slabs_equal_one_device_and_a_narrow_halo_does_not():
    """Over four devices, 300 fixed steps in which particles cross the cuts give
    the one-device positions, velocities and pressures to round-off (the sums
    over neighbours run in another order); a halo of one r_e (the step reads
    neighbours of neighbours) is off by far more. Adaptive steps take the same
    dt sequence as the one-device run."""
    out = _python(
        """
        c = case()
        one = jaxmps.simulate(c.scene, c.params, c.state, 300)
        run = jaxmps.simulate_slabs(c.scene, c.params, c.state, 300, 100, devices=4)
        act = one.state.active
        start_slab = np.searchsorted(run.cuts, np.asarray(c.state.position)[:, 0],
                                     side="right")
        end_slab = np.searchsorted(run.cuts, np.asarray(run.state.position)[:, 0],
                                   side="right")
        narrow = jaxmps.simulate_slabs(c.scene, c.params, c.state, 300, devices=4,
                                       halo=c.scene.r_e)
        a = case(dt="adaptive")
        one_a = jaxmps.simulate(a.scene, a.params, a.state, 60)
        run_a = jaxmps.simulate_slabs(a.scene, a.params, a.state, 60, devices=4)
        print(json.dumps(dict(
            devices=jax.device_count(),
            dx=apart(one.state.position, run.state.position, act),
            du=apart(one.state.velocity, run.state.velocity, act),
            dp=apart(one.state.pressure, run.state.pressure, act),
            p_max=float(np.max(np.asarray(one.state.pressure))),
            crossed=int(np.sum((start_slab != end_slab) & np.asarray(act))),
            saves=np.asarray(run.saved.time).tolist(),
            step=int(run.state.step),
            narrow=apart(one.state.position, narrow.state.position, act),
            time_one=float(one_a.state.time), time_slabs=float(run_a.state.time),
            dx_adaptive=apart(one_a.state.position, run_a.state.position, act),
        )))
        """,
        devices=4,
    )
    assert out["devices"] == 4
    assert out["crossed"] >= 10
    assert out["step"] == 300 and len(out["saves"]) == 3
    assert out["dx"] < 1e-12
    assert out["du"] < 1e-9
    assert out["dp"] < 1e-9 * out["p_max"]
    assert out["narrow"] > 1e-6
    assert out["time_slabs"] == pytest.approx(out["time_one"], rel=1e-12)
    assert out["dx_adaptive"] < 1e-12


def test_a_slab_that_overflows_stops_with_the_last_good_state():
    """With no slack and the slabs cut once, the slab the surge flows into runs
    out of slots: the run stops with `Result.slab_overflow` (raised with the run
    attached), its state the last good step's. Cut anew every 20 steps, the same
    slots suffice; with the default slack, so does one cut."""
    out = _python(
        """
        c = case()
        raised = None
        try:
            jaxmps.simulate_slabs(c.scene, c.params, c.state, 200, devices=2,
                                  slack=1.0)
        except jaxmps.SlabRunError as e:
            raised, run = str(e), e.run
        recut = jaxmps.simulate_slabs(c.scene, c.params, c.state, 200, 20,
                                      devices=2, slack=1.0)
        again = jaxmps.simulate_slabs(c.scene, c.params, c.state, 200, devices=2)
        one = jaxmps.simulate(c.scene, c.params, c.state, int(run.state.step))
        print(json.dumps(dict(
            raised=raised, step=int(run.state.step),
            overflow=bool(run.result == jaxmps.Result.slab_overflow),
            finite=bool(np.all(np.isfinite(np.asarray(run.state.position)))),
            dx=apart(one.state.position, run.state.position, one.state.active),
            again=bool(again.result == jaxmps.Result.successful),
            recut=bool(recut.result == jaxmps.Result.successful),
            peak=np.asarray(again.peak_owned).tolist(), slots=again.slots,
        )))
        """,
        devices=2,
    )
    assert out["raised"].startswith("slab_overflow") and "slack=" in out["raised"]
    assert out["overflow"] and out["finite"]
    assert 0 < out["step"] < 200
    assert out["dx"] < 1e-12
    assert out["again"] and max(out["peak"]) <= out["slots"]
    assert out["recut"]


def test_one_slab_is_the_one_device_run_bit_for_bit():
    """On one device the split run is the one-device step on the same particles:
    the same bits, and saves at the same times."""
    case = jaxmps.scenes.dam_break(solver="explicit", spacing=0.02)
    one = jaxmps.simulate(case.scene, case.params, case.state, 20, 10)
    run = jaxmps.simulate_slabs(case.scene, case.params, case.state, 20, 10)
    np.testing.assert_array_equal(one.state.position, run.state.position)
    np.testing.assert_array_equal(one.state.pressure, run.state.pressure)
    np.testing.assert_allclose(one.saved.time, run.saved.time)
    np.testing.assert_array_equal(one.saved.position, run.saved.position)
    assert int(run.state.step) == 20 and run.peak_halo.tolist() == [0]


def test_what_a_split_by_slabs_refuses():
    """Each refusal names the setting to change."""
    explicit = jaxmps.scenes.dam_break(solver="explicit", spacing=0.02)
    semi = jaxmps.scenes.dam_break(spacing=0.02)
    with pytest.raises(ValueError, match="solver='explicit'"):
        jaxmps.simulate_slabs(semi.scene, semi.params, semi.state, 10)
    box = jaxmps.scenes.floating_box(solver="explicit", spacing=0.02, settle=0)
    with pytest.raises(ValueError, match="rigid"):
        jaxmps.simulate_slabs(box.scene, box.params, box.state, 10)
    args = (explicit.scene, explicit.params, explicit.state)
    with pytest.raises(ValueError, match="slack"):
        jaxmps.simulate_slabs(*args, 10, slack=0.5)
    with pytest.raises(ValueError, match="n_steps"):
        jaxmps.simulate_slabs(*args, 0)
    with pytest.raises(ValueError, match="multiple of save_every"):
        jaxmps.simulate_slabs(*args, 10, 3)
    with pytest.raises(ValueError, match="halo"):
        jaxmps.simulate_slabs(*args, 10, halo=-1.0)
    with pytest.raises(ValueError, match="devices=9"):
        jaxmps.simulate_slabs(*args, 10, devices=9)


def test_a_domain_too_short_for_its_slabs_is_refused():
    """Eight slabs of the default (short) dam break at l0 = 2 cm cannot each be
    a halo wide: refused before anything runs, naming devices."""
    out = _python(
        """
        c = jaxmps.scenes.dam_break(solver="explicit", spacing=0.02)
        try:
            jaxmps.simulate_slabs(c.scene, c.params, c.state, 10, devices=8)
            print(json.dumps(dict(message=None)))
        except ValueError as e:
            print(json.dumps(dict(message=str(e))))
        """,
        devices=8,
    )
    assert "at least a halo" in out["message"]
    assert "devices=" in out["message"]
