"""Helpers shared by the benchmark (and validation) scripts: the machine
description, the load average and the compile-and-time harness."""

import dataclasses
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jaxlib

import jaxmps
from jaxmps import _result

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
        # A copy of the tree without its history (a lent GPU machine): the caller
        # may name the commit it copied.
        commit, dirty = os.environ.get("JAXMPS_GIT_COMMIT"), None
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
    return _result.result_name(result)


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


def compile_timed(lower, *args, **kwargs) -> tuple[Any, float, float]:
    """Lower and compile a program: (compiled, trace_lower_s, compile_s).

    Args:
        lower: returns the lowered program for `(*args, **kwargs)`, e.g.
            `jaxmps.lower_simulate` or `eqx.filter_jit(fn).lower`.
    """
    t0 = time.perf_counter()
    lowered = lower(*args, **kwargs)
    t1 = time.perf_counter()
    compiled = lowered.compile()
    return compiled, t1 - t0, time.perf_counter() - t1


def time_calls(
    call, repeats: int = 3, max_timed_s=math.inf
) -> tuple[Any, float, list[float]]:
    """Time a compiled call: one untimed warm-up call, then `repeats` timed calls,
    each ended by `jax.block_until_ready`; only one timed call when the warm-up
    took longer than `max_timed_s`. Returns (warm-up output, warmup_s, times).
    With `repeats=0` it makes the first call only, timed as `warmup_s` (for runs
    too long to repeat)."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(call())
    warmup_s = time.perf_counter() - t0
    times = []
    for _ in range(min(1, repeats) if warmup_s > max_timed_s else repeats):
        start = time.perf_counter()
        jax.block_until_ready(call())
        times.append(time.perf_counter() - start)
    return out, warmup_s, times


def time_compiled(lower, *args, repeats: int = 3, max_timed_s=math.inf, **kwargs):
    """Compile a program and time it the way every script here does: lower it and
    compile it (both timed, apart from running, `compile_timed`), one untimed
    warm-up call, then the best of `repeats` timed calls (`time_calls`).

    Args:
        lower: returns the lowered program for `(*args, **kwargs)`, e.g.
            `jaxmps.lower_simulate` or `eqx.filter_jit(fn).lower`; the compiled
            program is called with the same arguments.

    Returns:
        A `Timed`: the warm-up call's output, the compiled program, the timings.
    """
    compiled, trace_lower_s, compile_s = compile_timed(lower, *args, **kwargs)
    out, warmup_s, times = time_calls(
        lambda: compiled(*args, **kwargs), repeats, max_timed_s
    )
    return Timed(
        output=out,
        compiled=compiled,
        trace_lower_s=trace_lower_s,
        compile_s=compile_s,
        warmup_s=warmup_s,
        run_s_all=times,
    )


@eqx.filter_jit
def iteration_stats(scene, params, state, n_steps: int):
    """Pressure-solve iterations/convergence of each of `n_steps` steps."""

    def body(s, _):
        s, info = jaxmps.step(scene, params, s)
        return s, (info.pressure_iterations, info.pressure_converged)

    final, (iters, converged) = jax.lax.scan(body, state, None, length=n_steps)
    return final.result, iters, converged


def compile_and_run(scene, params, state, n_steps: int) -> tuple[float, float]:
    """(trace + lower + compile [s], best of 3 runs [s]) of `n_steps` steps saving
    the last frame (`time_compiled` of `jaxmps.lower_simulate`)."""
    import jaxmps

    timed = time_compiled(
        jaxmps.lower_simulate,
        scene,
        params,
        state,
        n_steps,
        n_steps,
        jaxmps.frame,
        throw=False,
    )
    return timed.trace_lower_s + timed.compile_s, timed.run_s_best


def fixed_steps(case):
    """`case` stepping by its `Params.dt` every step (its scene's largest step):
    the per-step cost the throughput scripts measure, comparable with the peers'
    fixed steps and with results before adaptive steps were the default
    (`adaptive_steps.py` measures adaptive steps)."""
    import equinox as eqx

    return eqx.tree_at(
        lambda c: c.scene.time_step, case, None, is_leaf=lambda x: x is None
    )


def rows_per_device_count(script: str, counts, child_args: list[str]) -> list[dict]:
    """Run `script --child N *child_args` in a process of its own per device count
    N (CPU devices forced with XLA_FLAGS unless JAX sees a GPU: then the GPUs
    there are) and gather the JSON rows (lines starting with "{") it prints."""
    gpu = jax.default_backend() == "gpu"
    rows = []
    for d in counts:
        env = dict(os.environ)
        if not gpu:
            env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={d}"
        done = subprocess.run(
            [sys.executable, script, "--child", str(d), *child_args],
            capture_output=True,
            text=True,
            env=env,
            cwd=HERE,
        )
        if done.returncode:
            raise SystemExit(done.stderr[-3000:])
        rows += [json.loads(x) for x in done.stdout.splitlines() if x[:1] == "{"]
    return rows


def write_rows(name: str, out: str | None, rows: list[dict], markdown) -> Path:
    """Write `rows` with the machine's description to `out` (default
    results/<name>_<backend>) as .json, and `markdown(info, rows)` as .md."""
    info = machine_info()
    path = Path(out) if out else HERE / "results" / f"{name}_{info['backend']}"
    path.with_suffix(".json").write_text(
        json.dumps(dict(machine=info, rows=rows), indent=1)
    )
    path.with_suffix(".md").write_text(markdown(info, rows))
    print(f"wrote {path}.{{json,md}}")
    return path
