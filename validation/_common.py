"""Helpers shared with the benchmarks: the machine description, the load average
and the compile-and-time harness of `benchmarks/_common.py`, loaded by path so that
the scripts of both folders run as plain files (`python validation/<script>.py`)."""

import importlib.util
from pathlib import Path

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
