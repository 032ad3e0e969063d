"""Helpers shared with the benchmarks: the machine description, the load average
and the compile-and-time harness of `benchmarks/_common.py`, loaded by path so that
the scripts of both folders run as plain files (`python validation/<script>.py`);
the free-decay fit (`jaxmps.calibration.fit_damped_oscillation`) and a
zero-crossing period."""

import importlib.util
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
