"""Helpers shared with the benchmarks: the machine description, the load average
and the compile-and-time harness of `benchmarks/_common.py`, loaded by path so that
the scripts of both folders run as plain files (`python validation/<script>.py`);
the free-decay fit (`jaxmps.calibration.fit_damped_oscillation`) and a
zero-crossing period."""

import importlib.util
import time
from pathlib import Path

import numpy as np

from jaxmps.calibration import fit_damped_oscillation as damped_fit  # noqa: F401

_path = Path(__file__).resolve().parents[1] / "benchmarks" / "_common.py"
_spec = importlib.util.spec_from_file_location("jaxmps_benchmarks_common", _path)
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)

HERE = Path(__file__).resolve().parent
loadavg = _module.loadavg
machine_info = _module.machine_info
result_name = _module.result_name
compile_timed = _module.compile_timed
time_calls = _module.time_calls
time_compiled = _module.time_compiled


def crossing_period(t, y):
    m = y - y.mean()
    i = np.nonzero(np.sign(m[:-1]) != np.sign(m[1:]))[0]
    crossings = t[i] - m[i] * (t[i + 1] - t[i]) / (m[i + 1] - m[i])
    return 2 * float(np.mean(np.diff(crossings))), len(crossings)


def shaken_sweep(case, freqs, settle, shake, save_every=10):
    """A shaken tank's `case` run for `settle` + `shake` s at each frequency of
    `freqs`, as one vmapped batch: (the `SweepResult`, steps, wall seconds, the
    saves' times, the mask of saves while shaking)."""
    import jaxmps

    dt = float(case.params.dt)
    steps = int((settle + shake) / dt) // save_every * save_every
    start = time.perf_counter()
    out = jaxmps.sweep(case, {"motion.frequency": np.asarray(freqs)}, steps, save_every)
    wall = time.perf_counter() - start
    t = np.asarray(out.saved["time"])[0]
    return out, steps, wall, t, t > settle


def free_decay(case, periods, probe="mode", save_every=5):
    """A released standing wave's `case` run for `periods` of its linear period:
    (the trajectory, steps, wall seconds, the saves' times, the `probe`'s
    record)."""
    import jaxmps

    steps = int(periods * case.config["linear_period"] / float(case.params.dt))
    steps = steps // save_every * save_every
    observe = jaxmps.scenes.observe_probes(case.probes)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene, case.params, case.state, steps, save_every, observe
    )
    wall = time.perf_counter() - start
    return out, steps, wall, np.asarray(out.saved["time"]), np.asarray(out.saved[probe])
