"""Helpers shared by the benchmark (and validation) scripts: the machine
description, the load average and the compile-and-time harness."""

import dataclasses
import math
import os
import platform
import subprocess
import time
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jaxlib

import jaxmps

HERE = Path(__file__).resolve().parent


def loadavg() -> float | None:
    """1-minute load average (other processes competing for the cores), or None."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):
        return None


def _git(*args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=HERE, capture_output=True, text=True, check=True
    ).stdout.strip()


def machine_info() -> dict:
    """What ran the benchmark: platform, CPU, versions, device, dtype, git commit."""
    cpu_model = None
    try:
        # The first processor's block. Virtual machines often name only the vendor
        # line ("AMD EPYC"), so family, model and the widest vector set are kept:
        # XLA's CPU code ran 2x apart on two hosts both called "AMD EPYC".
        block = Path("/proc/cpuinfo").read_text().split("\n\n")[0]
        info = dict(
            (k.strip(), v.strip())
            for k, _, v in (ln.partition(":") for ln in block.splitlines())
        )
        flags = set(info.get("flags", "").split())
        vector = next((f for f in ("avx512f", "avx2", "avx") if f in flags), None)
        cpu_model = (
            ", ".join(
                x
                for x in (
                    info.get("model name"),
                    f"family {info['cpu family']} model {info['model']}"
                    if "cpu family" in info and "model" in info
                    else None,
                    vector,
                )
                if x
            )
            or None
        )
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    try:
        commit = _git("rev-parse", "--short", "HEAD")
        dirty = bool(_git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.CalledProcessError):
        commit, dirty = None, None
    device = jax.devices()[0]
    return {
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_model": cpu_model,
        "cpu_count": os.cpu_count(),
        "cpu_usable": usable,
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "equinox": eqx.__version__,
        "jaxmps": jaxmps.__version__,
        "backend": jax.default_backend(),
        "device": f"{device.platform}:{getattr(device, 'device_kind', '?')}",
        "dtype": str(jnp.zeros(()).dtype),
        "jax_enable_x64": bool(jax.config.jax_enable_x64),
        "git_commit": commit,
        "git_dirty_tracked": dirty,
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "loadavg_1min_start": loadavg(),
    }


def result_name(result) -> str:
    """Name of a `jaxmps.Result` value ("successful", "nonfinite_state", ...)."""
    for name in jaxmps.Result._name_to_item:
        if bool(result == getattr(jaxmps.Result, name)):
            return name
    return str(result)


@dataclasses.dataclass
class Timed:
    """A compiled program, its first output and its timings [s]."""

    output: Any
    compiled: Any
    trace_lower_s: float
    compile_s: float
    warmup_s: float
    run_s_all: list[float]

    @property
    def run_s_best(self) -> float:
        return min(self.run_s_all)

    def timing(self) -> dict:
        """The timings as a JSON-ready dict."""
        return {
            "trace_lower_s": self.trace_lower_s,
            "compile_s": self.compile_s,
            "warmup_s": self.warmup_s,
            "run_s_all": self.run_s_all,
            "run_s_best": self.run_s_best,
        }


def time_compiled(lower, *args, repeats: int = 3, max_timed_s=math.inf, **kwargs):
    """Compile a program and time it the way every script here does: lower it and
    compile it (both timed, apart from running), one untimed warm-up call, then the
    best of `repeats` timed calls, each ended by `jax.block_until_ready`; only one
    timed call when the warm-up took longer than `max_timed_s`.

    Args:
        lower: returns the lowered program for `(*args, **kwargs)`, e.g.
            `jaxmps.lower_simulate` or `eqx.filter_jit(fn).lower`; the compiled
            program is called with the same arguments.

    Returns:
        A `Timed`: the warm-up call's output, the compiled program, the timings.
    """
    t0 = time.perf_counter()
    lowered = lower(*args, **kwargs)
    t1 = time.perf_counter()
    compiled = lowered.compile()
    t2 = time.perf_counter()
    out = jax.block_until_ready(compiled(*args, **kwargs))
    t3 = time.perf_counter()
    times = []
    for _ in range(1 if t3 - t2 > max_timed_s else repeats):
        start = time.perf_counter()
        jax.block_until_ready(compiled(*args, **kwargs))
        times.append(time.perf_counter() - start)
    return Timed(
        output=out,
        compiled=compiled,
        trace_lower_s=t1 - t0,
        compile_s=t2 - t1,
        warmup_s=t3 - t2,
        run_s_all=times,
    )
