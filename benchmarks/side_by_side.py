"""Side by side: `jaxmps` vs JAX-SPH and PySPH (weakly compressible SPH) on a 2-D
dam break.

jaxmps and JAX-SPH run the same dam break (a 0.146 x 0.292 m water column at the
left wall of a 0.584 m tank, 0.438 m high) at matched total particle counts (fluid
+ walls, dummies included) of about 7 k, 25 k and 90 k:

* JAX-SPH 0.1.0 (PyPI `jax-sph`): its WCSPH solver with its own dam-break settings
  (density evolution, artificial viscosity 0.1, generalized wall BC, quintic spline
  kernel, 3 wall layers, closed tank, dt from its CFL rule), set up against its
  public API in `_jaxsph_worker.py`, dx = 0.146 m / n, n = 49 / 102 / 202 (6896 /
  25128 / 90128 particles). The steps, including the neighbour-list update, are
  rolled out with `jax.lax.scan`.
* jaxmps: `jaxmps.scenes.dam_break(spacing=0.146 m / m, solver=...)` with the
  whole number m of particles across the column that brings `scene.capacity`
  nearest to JAX-SPH's count; rolled out with `jaxmps.simulate(..., throw=False)`
  and an observe function that saves only the time.

* PySPH 1.0b2 (PyPI `pysph`, compiled C through Cython, not differentiable): its
  own `dam_break_2d` example (a 1 x 2 m column in a 4 x 4 m tank) with h and m
  reset from dx (`_pysph_worker.py`), dx = 1/k m with the count nearest the target,
  OpenMP on all cores, double precision, once per size; built on first use into
  `--pysph-venv` (default `benchmarks/.venv-pysph`; some 8 minutes on 2 cores).
  When the build fails or takes longer than `--pysph-limit` the reason is printed
  and saved, and the other codes are still measured.

JAX-SPH needs Python <= 3.11.0 and pins jax 0.4.29, so it runs in its own virtual
environment (created on first use under `--peer-venv`, default
`benchmarks/.venv-jaxsph`, from `--peer-python` or the first python3.10 / 3.9 /
~/.pyenv/versions/3.10* found; `pip install jax-sph==0.1.0`). If none can be made
the script says why and measures jaxmps only.

Every (code, dtype, size) runs in a fresh subprocess, alternating the codes (per
size: jaxmps float64, JAX-SPH float64, PySPH, jaxmps float32, JAX-SPH float32, ...),
so that background load hits both. In each: compile time (trace + lower, XLA
compile) via `.lower(...).compile()`, then one untimed warm-up call and the best of
`--repeats` timed calls of `--steps` steps, each ended by `jax.block_until_ready`;
particle-steps/s = particles x steps / run time, wall time per simulated second =
run time / (steps x dt) (the codes' dt differ), and the peak RSS of the subprocess.

Usage:
    python benchmarks/side_by_side.py                          # 7k and 25k, 200 steps
    python benchmarks/side_by_side.py --sizes 90k --steps 50 --repeats 1 --append
    python benchmarks/side_by_side.py --sizes 7k --steps 20 --out /tmp/quick
    python benchmarks/side_by_side.py --sizes 7k 25k 90k --dtypes float64
    python benchmarks/side_by_side.py --peer-venv /path/to/venv --solvers explicit

Writes `benchmarks/results/side_by_side_<backend>.json` and `.md` (override with
`--out`, a path without extension).
"""

import argparse
import glob
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
WORKER = HERE / "_jaxsph_worker.py"
PYSPH_WORKER = HERE / "_pysph_worker.py"
PYSPH_VERSION = "1.0b2"
COLUMN_WIDTH = 0.146  # m, as jaxmps.scenes.dam_break's default
JAX_SPH_VERSION = "0.1.0"
SIZES = {"7k": 7_000, "25k": 25_000, "90k": 90_000}


# ----------------------------------------------------------------------------- sizes


def jaxsph_count(n: int) -> int:
    """Particles of the JAX-SPH case with n across the column: the column (n x 2n)
    and a closed tank (4n x 3n inside) with 3 wall layers all round."""
    return 2 * n * n + 2 * 3 * (3 * n + 2 * 3) + 2 * 3 * 4 * n


def parse_size(text: str) -> int:
    """'7k' -> 7000, '25000' -> 25000."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kK]?)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"size {text!r}: use e.g. 7k or 25000")
    return int(round(float(m.group(1)) * (1000 if m.group(2) else 1)))


def jaxsph_n_across(target: int) -> int:
    """n across the column whose JAX-SPH particle count is nearest `target`."""
    n = max(2, int((target / 2) ** 0.5))
    candidates = range(max(2, n - 30), n + 30)
    return min(candidates, key=lambda k: abs(jaxsph_count(k) - target))


def jaxmps_match(target: int, solver: str) -> tuple[int, int]:
    """(m across the column, capacity) of `jaxmps.scenes.dam_break` with the
    capacity nearest `target` (capacity grows with m; bisection)."""
    import jaxmps

    cache: dict[int, int] = {}

    def capacity(m: int) -> int:
        if m not in cache:
            case = jaxmps.scenes.dam_break(spacing=COLUMN_WIDTH / m, solver=solver)
            cache[m] = int(case.scene.capacity)
        return cache[m]

    lo, hi = 2, max(4, int((target / 2) ** 0.5) + 2)
    while capacity(hi) < target:
        lo, hi = hi, 2 * hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if capacity(mid) < target else (lo, mid)
    m = min((lo, hi), key=lambda k: abs(capacity(k) - target))
    return m, capacity(m)


# ----------------------------------------------------------------------------- jaxmps


def jaxmps_worker(
    spacing: float,
    solver: str,
    n_steps: int,
    repeats: int,
    max_timed_s,
    dtype,
    start_time: float = 0.0,
):
    """One jaxmps measurement (runs in its own process; dtype set before any
    array is made), from the state at `start_time` [s] (rolled out untimed)."""
    import jax

    jax.config.update("jax_enable_x64", dtype == "float64")
    import jax.numpy as jnp
    from _common import fixed_steps, loadavg, time_compiled
    from step_throughput import _memory_analysis_mib, _rss_mib, observe_time

    import jaxmps

    case = fixed_steps(jaxmps.scenes.dam_break(spacing=spacing, solver=solver))
    scene, params, state = case.scene, case.params, case.state
    start_steps = int(round(start_time / float(params.dt)))
    if start_steps:
        state = jaxmps.simulate(
            scene, params, state, start_steps, start_steps, observe_time, throw=False
        ).state
    jax.block_until_ready((params, state))
    n_fluid = int(jnp.sum(state.kind == int(jaxmps.Kind.FLUID)))
    args = (scene, params, state, n_steps, None, observe_time)
    kwargs = dict(throw=False)
    timed = time_compiled(
        jaxmps.lower_simulate,
        *args,
        repeats=repeats,
        max_timed_s=max_timed_s,
        **kwargs,
    )
    traj, compiled = timed.output, timed.compiled
    t_lower, t_compile = timed.trace_lower_s, timed.compile_s
    best, times = timed.run_s_best, timed.run_s_all
    dt = float(params.dt)
    fluid = traj.state.kind == int(jaxmps.Kind.FLUID)
    speed = jnp.linalg.norm(traj.state.velocity, axis=1)
    return {
        "code": "jaxmps",
        "solver": solver,
        "spacing": spacing,
        "n_across": int(round(COLUMN_WIDTH / spacing)),
        "capacity": int(scene.capacity),
        "n_fluid": n_fluid,
        "n_wall": int(scene.capacity) - n_fluid,
        "dt": dt,
        "n_steps": n_steps,
        "start_steps": start_steps,
        "simulated_time": float(traj.state.time),
        "dtype": str(state.position.dtype),
        "jax_enable_x64": bool(jax.config.jax_enable_x64),
        "trace_lower_s": t_lower,
        "compile_s": t_compile,
        "run_s_best": best,
        "run_s_all": times,
        "ms_per_step": 1e3 * best / n_steps,
        "particle_steps_per_s": scene.capacity * n_steps / best,
        "wall_per_simulated_s": best / (n_steps * dt),
        "result": str(traj.result),
        "finite": bool(traj.result == jaxmps.Result.successful),
        "fluid_u_max": float(jnp.max(jnp.where(fluid, speed, 0.0))),
        "peak_rss_mib": _rss_mib(),
        "xla_memory_analysis": _memory_analysis_mib(compiled),
        "loadavg_1min_end": loadavg(),
    }


# ------------------------------------------------------------------------- peer venv


def _python_version(python: str) -> tuple[int, int, int] | None:
    try:
        out = subprocess.run(
            [python, "-c", "import sys; print(*sys.version_info[:3])"],
            capture_output=True,
            text=True,
            timeout=60,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    if out.returncode != 0:
        return None
    try:
        return tuple(int(x) for x in out.stdout.split()[:3])
    except ValueError:
        return None


def _fits_jaxsph(version) -> bool:
    """jax-sph 0.1.0 declares Python >= 3.9, <= 3.11.0."""
    return version is not None and (3, 9, 0) <= version <= (3, 11, 0)


def find_peer_python(explicit: str | None) -> tuple[str | None, list[str]]:
    """An interpreter JAX-SPH can be installed into, and what was tried."""
    tried = []
    candidates = [explicit] if explicit else []
    candidates += [shutil.which(n) for n in ("python3.10", "python3.9", "python3.11")]
    home = Path.home() / ".pyenv" / "versions"
    for pattern in ("3.10*", "3.9*", "3.11.0"):
        candidates += sorted(glob.glob(str(home / pattern / "bin" / "python")))
    for c in candidates:
        if not c:
            continue
        version = _python_version(c)
        tried.append(f"{c}: {'.'.join(map(str, version)) if version else 'no run'}")
        if _fits_jaxsph(version):
            return c, tried
    return None, tried


def _venv_has_jaxsph(python: Path) -> bool:
    if not python.exists():
        return False
    check = (
        "import importlib.metadata as m, jax_sph.solver; "
        f"assert m.version('jax-sph') == '{JAX_SPH_VERSION}'"
    )
    return (
        subprocess.run([str(python), "-c", check], capture_output=True).returncode == 0
    )


def ensure_peer(venv: Path, explicit_python: str | None) -> tuple[str | None, str]:
    """Python of a venv with jax-sph installed (made if needed), and a status line."""
    python = venv / "bin" / "python"
    if _venv_has_jaxsph(python):
        return str(python), f"using existing venv {venv}"
    base, tried = find_peer_python(explicit_python)
    if base is None:
        return None, (
            "no Python >= 3.9, <= 3.11.0 found for jax-sph 0.1.0 (tried: "
            + "; ".join(tried)
            + "); pass --peer-python"
        )
    print(f"creating {venv} with {base} and installing jax-sph=={JAX_SPH_VERSION}")
    steps = [
        [base, "-m", "venv", "--clear", str(venv)],
        [str(python), "-m", "pip", "install", "-q", f"jax-sph=={JAX_SPH_VERSION}"],
    ]
    for cmd in steps:
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
            return None, f"{' '.join(cmd[:4])} failed: {' | '.join(tail)}"
    if not _venv_has_jaxsph(python):
        return None, f"jax-sph not importable in {venv} after install"
    return str(python), f"created venv {venv} ({base})"


def _venv_has_pysph(python: Path) -> bool:
    check = (
        "import importlib.metadata as m; "
        f"assert m.version('pysph') == '{PYSPH_VERSION}'"
    )
    return python.exists() and (
        subprocess.run([str(python), "-c", check], capture_output=True).returncode == 0
    )


def ensure_pysph(venv: Path, limit_s: float) -> dict:
    """A venv with PySPH (made and built if needed, within `limit_s`)."""
    t0 = time.perf_counter()
    python = venv / "bin" / "python"
    if _venv_has_pysph(python):
        return {"python": str(python), "status": f"using existing venv {venv}"}
    print(f"creating {venv} and building pysph=={PYSPH_VERSION} (several minutes)")
    cmds = [
        [sys.executable, "-m", "venv", "--clear", str(venv)],
        [str(python), "-m", "pip", "install", "-q", f"pysph=={PYSPH_VERSION}"],
    ]
    for cmd in cmds:
        left = limit_s - (time.perf_counter() - t0)
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=left)
        except subprocess.TimeoutExpired:
            return {
                "python": None,
                "status": f"`{' '.join(cmd[-3:])}` did not finish within "
                f"{limit_s:.0f} s (PySPH is a source distribution: pip builds it "
                "and its build dependencies - Cython, compyle, cyarray - first; "
                "raise --pysph-limit)",
            }
        if proc.returncode != 0:
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
            return {
                "python": None,
                "status": f"`{' '.join(cmd[-3:])}` failed: {' | '.join(tail)}",
            }
    seconds = time.perf_counter() - t0
    return {"python": str(python), "status": f"built {venv} in {seconds:.0f} s"}


def pysph_match(python: str, target: int) -> tuple[float, int]:
    """(dx = 1/k m, particles) of PySPH's dam break with the count nearest `target`
    (whole k, so that its fluid block is a whole number of spacings)."""
    cache: dict[int, int] = {}

    def count(k: int) -> int:
        if k not in cache:
            cmd = [python, str(PYSPH_WORKER), "--dx", repr(1.0 / k), "--count-only"]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True)
            cache[k] = json.loads(out.stdout.strip().splitlines()[-1])["particles"]
        return cache[k]

    # The example's 1 x 2 m column in a 4 x 4 m tank: ~2 k^2 fluid particles.
    k = max(5, round((target / 3.0) ** 0.5))
    while count(k) < target:
        k = round(k * 1.2) + 1
    while k > 5 and count(k - 1) >= target:
        k -= 1
    best = min((k - 1, k), key=lambda j: abs(count(j) - target))
    return 1.0 / best, count(best)


# ----------------------------------------------------------------------------- driver


def _run(cmd: list[str], timeout: float | None) -> dict:
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, capture_output=True, text=True, cwd=HERE, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:.0f} s"}
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = proc.stderr.strip().splitlines()[-5:]
        sys.stderr.write(proc.stderr[-4000:])
        return {"error": f"exit {proc.returncode}: {' | '.join(tail)}"}
    record = json.loads(proc.stdout.strip().splitlines()[-1])
    record["process_wall_s"] = wall
    return record


def run_jaxmps(m: int, solver: str, dtype: str, args) -> dict:
    cmd = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--worker-jaxmps",
        repr(COLUMN_WIDTH / m),
        "--solvers",
        solver,
        "--dtypes",
        dtype,
        "--steps",
        str(args.steps),
        "--repeats",
        str(args.repeats),
        "--max-timed-s",
        str(args.max_timed_s),
        "--start-time",
        str(args.start_time),
    ]
    return _run(cmd, args.timeout)


def run_jaxsph(python: str, n: int, dtype: str, args) -> dict:
    cmd = [
        python,
        str(WORKER),
        "--n-across",
        str(n),
        "--column-width",
        repr(COLUMN_WIDTH),
        "--steps",
        str(args.steps),
        "--repeats",
        str(args.repeats),
        "--dtype",
        dtype,
        "--max-timed-s",
        str(args.max_timed_s),
    ]
    return _run(cmd, args.timeout)


def run_pysph(python: str, dx: float, args) -> dict:
    cmd = [
        python,
        str(PYSPH_WORKER),
        "--dx",
        repr(dx),
        "--steps",
        str(args.steps),
        "--repeats",
        str(args.repeats),
        "--openmp",
    ]
    r = _run(cmd, args.timeout)
    if "error" not in r:
        # Common columns: PySPH's setup (code generation + Cython compile or
        # cache load + 50 warm-up steps) stands in the compile column.
        r.update(
            capacity=r["particles"],
            trace_lower_s=0.0,
            compile_s=r["setup_s"],
            run_s_best=r["run_s"],
            dtype="float64",
            solver="WCSPH",
        )
    return r


def _g(x, fmt=".3g"):
    return "-" if x is None else format(x, fmt)


def _label(r: dict) -> str:
    if r["code"] == "PySPH":
        return f"PySPH (OpenMP, {r['n_threads']} threads)"
    return "JAX-SPH" if r["code"] == "jax-sph" else f"jaxmps {r['solver']}"


def ratios(rows: list[dict]) -> list[dict]:
    """jaxmps vs JAX-SPH per (size, dtype, solver), best over rounds."""
    best: dict[tuple, dict] = {}
    for r in rows:
        if "error" in r:
            continue
        key = (r["size"], r["dtype_requested"], r.get("solver", "WCSPH"), r["code"])
        if key not in best or r["run_s_best"] < best[key]["run_s_best"]:
            best[key] = r
    out = []
    for (size, dtype, solver, code), r in best.items():
        if code != "jaxmps":
            continue
        row = {
            "size": size,
            "dtype": dtype,
            "solver": solver,
            "jaxmps_particles": r["capacity"],
            "jaxmps_particle_steps_per_s": r["particle_steps_per_s"],
            "jaxmps_wall_per_simulated_s": r["wall_per_simulated_s"],
        }
        peer = best.get((size, dtype, "SPH", "jax-sph"))
        if peer is not None:
            row.update(
                jaxsph_particles=peer["capacity"],
                jaxsph_particle_steps_per_s=peer["particle_steps_per_s"],
                throughput_ratio=r["particle_steps_per_s"]
                / peer["particle_steps_per_s"],
                jaxsph_wall_per_simulated_s=peer["wall_per_simulated_s"],
                simulated_time_speed_ratio=peer["wall_per_simulated_s"]
                / r["wall_per_simulated_s"],
                dt_ratio=r["dt"] / peer["dt"],
            )
        # PySPH computes in double precision only: both jaxmps dtypes are
        # compared with its one run per size.
        pysph = best.get((size, "float64", "WCSPH", "PySPH"))
        if pysph is not None:
            row.update(
                pysph_particles=pysph["capacity"],
                pysph_particle_steps_per_s=pysph["particle_steps_per_s"],
                pysph_ratio=r["particle_steps_per_s"] / pysph["particle_steps_per_s"],
                pysph_wall_per_simulated_s=pysph["wall_per_simulated_s"],
            )
        if peer is not None or pysph is not None:
            out.append(row)
    return out


def markdown(info: dict, rows, ratio_rows, peer: dict, pysph, args) -> str:
    tag = f"CPU ({info['cpu_usable']} cores)" if info["backend"] == "cpu" else "GPU"
    pv = next((r["versions"] for r in rows if r.get("code") == "jax-sph"), None)
    lines = [
        f"# Side by side: jaxmps vs JAX-SPH and PySPH, 2-D dam break, {tag}",
        "",
        f"- machine: {info['platform']}, {info['cpu_model']}, "
        f"{info['cpu_usable']} usable / {info['cpu_count']} CPUs",
        f"- jaxmps: jax {info['jax']} (jaxlib {info['jaxlib']}), equinox "
        f"{info['equinox']}, jaxmps {info['jaxmps']}, python {info['python']}; git "
        f"{info['git_commit']}"
        + (" (uncommitted changes)" if info["git_dirty_tracked"] else ""),
        "- JAX-SPH: "
        + (
            f"jax-sph {pv['jax_sph']}, jax {pv['jax']} (jaxlib {pv['jaxlib']}), "
            f"python {pv['python']}"
            if pv
            else "not run"
        )
        + f" ({peer['status']})",
        "- rows by commit (None: an earlier version that did not record it): "
        + "; ".join(
            f"{c}: "
            + ", ".join(sorted({_label(r) for r in rows if r.get("git_commit") == c}))
            for c in sorted({r.get("git_commit") for r in rows}, key=str)
        ),
        f"- 1-min load average: {_g(info.get('loadavg_1min_start'), '.2f')} at "
        f"start, {_g(info.get('loadavg_1min_end'), '.2f')} at end (> core count "
        "means other processes competed for the CPU)",
        "- run = best of --repeats calls (see `settings` in the JSON; 1 at 90k) "
        "after one untimed warm-up call (one call where the warm-up took > "
        f"{args.max_timed_s:g} s; "
        "`run_s_all` in the JSON); compile (trace+lower / XLA) measured "
        "separately; every row is a fresh subprocess, jaxmps and JAX-SPH "
        "alternating; peak RSS is that subprocess's (Python, jax and the "
        "compiler included).",
        "- jaxmps rows timed from "
        + (
            f"t = {args.start_time:g} s of the dam break (rolled out untimed "
            "first; the flow is in motion and the neighbour lists are searched "
            "more often than from rest)"
            if args.start_time
            else "rest (t = 0; `--start-time` times a later, moving state)"
        )
        + "; PySPH after its 50 warm-up steps.",
        "",
        "| size | code | dtype | particles (fluid) | spacing [mm] | dt [µs] "
        "| compile [s] | steps | run [s] | ms/step | particle-steps/s "
        "| wall / sim. s [s] | peak RSS [MiB] | ok |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(
                f"| {r['size']} | {r['code']} | {r['dtype_requested']} "
                f"| {r['error']} |" + " |" * 10
            )
            continue
        spacing = r.get("spacing", r.get("dx"))
        lines.append(
            f"| {r['size']} | {_label(r)} | {r['dtype']} "
            f"| {r['capacity']} ({r['n_fluid']}) | {1e3 * spacing:.3f} "
            f"| {1e6 * r['dt']:.1f} "
            f"| {r['trace_lower_s'] + r['compile_s']:.1f} "
            f"({r['trace_lower_s']:.1f} / {r['compile_s']:.1f}) "
            f"| {r['n_steps']} | {r['run_s_best']:.2f} | {r['ms_per_step']:.1f} "
            f"| {r['particle_steps_per_s']:.3g} | {r['wall_per_simulated_s']:.0f} "
            f"| {r['peak_rss_mib']:.0f} | {'yes' if r['finite'] else 'NO'} |"
        )
    if ratio_rows:
        lines += [
            "",
            "## Ratios (jaxmps / peer; > 1 means jaxmps is faster)",
            "",
            "| size | dtype | jaxmps solver | particles jaxmps / JAX-SPH / PySPH "
            "| particle-steps/s jaxmps / JAX-SPH / PySPH "
            "| **vs JAX-SPH** | **vs PySPH** | dt ratio vs JAX-SPH "
            "| wall per sim. s: jaxmps / JAX-SPH / PySPH [s] |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for q in ratio_rows:
            lines.append(
                f"| {q['size']} | {q['dtype']} | {q['solver']} "
                f"| {q['jaxmps_particles']} / {q.get('jaxsph_particles', '-')} / "
                f"{q.get('pysph_particles', '-')} "
                f"| {q['jaxmps_particle_steps_per_s']:.3g} / "
                f"{_g(q.get('jaxsph_particle_steps_per_s'))} / "
                f"{_g(q.get('pysph_particle_steps_per_s'))} "
                f"| **{_g(q.get('throughput_ratio'), '.2f')}** "
                f"| **{_g(q.get('pysph_ratio'), '.2f')}** "
                f"| {_g(q.get('dt_ratio'), '.2f')} "
                f"| {q['jaxmps_wall_per_simulated_s']:.0f} / "
                f"{_g(q.get('jaxsph_wall_per_simulated_s'), '.0f')} / "
                f"{_g(q.get('pysph_wall_per_simulated_s'), '.0f')} |"
            )
        per_sim = {}
        for q in ratio_rows:
            per_sim.setdefault((q["size"], q["dtype"]), {})[q["solver"]] = q
        pairs = [(k, v) for k, v in per_sim.items() if len(v) == 2]
        if pairs:
            lines += [
                "",
                "## Semi-implicit vs explicit MPS per simulated second",
                "",
                "| size | dtype | wall per sim. s explicit / semi-implicit [s] "
                "| explicit / semi-implicit |",
                "|---|---|---|---|",
            ]
            for (size, dtype), v in pairs:
                e = v["explicit"]["jaxmps_wall_per_simulated_s"]
                si = v["semi_implicit"]["jaxmps_wall_per_simulated_s"]
                lines.append(
                    f"| {size} | {dtype} | {e:.0f} / {si:.0f} | {e / si:.2f} |"
                )
    lines += [
        "",
        "Throughput ratio = particle-steps/s of jaxmps / of the peer (cost per "
        "particle and step). The wall time per simulated second also contains the "
        "codes' different time steps (dt ratio = jaxmps dt / JAX-SPH dt) and the "
        "small differences in particle count.",
        "",
        "JAX-SPH case: WCSPH (`solver.name = SPH`), density evolution, artificial "
        "viscosity alpha = 0.1, generalized wall BC, quintic spline kernel (h = dx, "
        "cut-off 3 dx), 3 wall layers round a closed 0.584 x 0.438 m tank, rho = "
        "1000, eta = 1e-3 Pa s, g = 9.81, c = 10 sqrt(2 g H) = 23.9 m/s, dt = 0.25 dx "
        "/ (c + u_ref); neighbour list `jaxmd_vmap` (rebuilt every step, inside the "
        "scan). jaxmps: `scenes.dam_break` defaults (open tank, walls + dummies).",
        "",
        "PySPH case (`_pysph_worker.py`): its `dam_break_2d` example (1 x 2 m column, "
        "4 x 4 m tank, WCSPH, Wendland quintic kernel, PEC integrator, adaptive dt "
        "at CFL 0.3) with h = 1.3 dx and m = rho dx^2 reset from dx; compiled C via "
        "Cython, OpenMP on all cores, double precision; its compile column is the "
        "set-up (code generation + compile or cache load + 50 warm-up steps), "
        "and it runs once per size (float64 rows). Its column and tank are 7x "
        "larger than the others' (a larger dt per spacing), so compare it by "
        "particle-steps/s, not per simulated second.",
    ]
    if pysph is not None:
        lines += ["", f"PySPH: {pysph['status']}"]
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--sizes",
        nargs="+",
        default=["7k", "25k"],
        help="target particle counts, e.g. 7k 25k 90k (default 7k 25k)",
    )
    p.add_argument("--steps", type=int, default=200, help="steps per run")
    p.add_argument("--repeats", type=int, default=3, help="timed calls (best taken)")
    p.add_argument(
        "--max-timed-s",
        type=float,
        default=20.0,
        help="time only one call when the warm-up call took longer than this [s]",
    )
    p.add_argument(
        "--dtypes",
        nargs="+",
        default=["float64", "float32"],
        choices=["float64", "float32"],
    )
    p.add_argument(
        "--solvers",
        nargs="+",
        default=["explicit", "semi_implicit"],
        choices=["explicit", "semi_implicit"],
        help="jaxmps solver(s) (default both)",
    )
    p.add_argument(
        "--rounds",
        type=int,
        default=1,
        help="alternating rounds per size and dtype (the best round is compared)",
    )
    p.add_argument("--peer-python", help="interpreter for the JAX-SPH venv")
    p.add_argument(
        "--peer-venv",
        type=Path,
        default=HERE / ".venv-jaxsph",
        help="JAX-SPH venv (created if missing; default benchmarks/.venv-jaxsph)",
    )
    p.add_argument("--no-peer", action="store_true", help="measure jaxmps only")
    p.add_argument("--no-pysph", action="store_true", help="skip PySPH")
    p.add_argument(
        "--pysph-venv",
        type=Path,
        default=HERE / ".venv-pysph",
        help="PySPH venv (built if missing; default benchmarks/.venv-pysph)",
    )
    p.add_argument(
        "--pysph-limit",
        type=float,
        default=1800.0,
        help="give up building PySPH after this many seconds (8 min measured here)",
    )
    p.add_argument(
        "--append",
        action="store_true",
        help="keep the rows already in the --out JSON and add these (e.g. a 90k "
        "row run with fewer steps); rows of the (size, dtype, code, solver) "
        "measured now replace the old ones",
    )
    p.add_argument(
        "--timeout", type=float, default=None, help="limit per subprocess [s]"
    )
    p.add_argument(
        "--start-time",
        type=float,
        default=0.0,
        help="jaxmps rows: time the steps from this time of the dam break [s] "
        "(rolled out untimed first; 0: from rest)",
    )
    p.add_argument("--out", type=Path, default=None, help="path without extension")
    p.add_argument("--worker-jaxmps", type=float, help=argparse.SUPPRESS)
    args = p.parse_args(argv)

    if args.worker_jaxmps is not None:
        rec = jaxmps_worker(
            args.worker_jaxmps,
            args.solvers[0],
            args.steps,
            args.repeats,
            args.max_timed_s,
            args.dtypes[0],
            args.start_time,
        )
        print(json.dumps(rec))
        return

    from _common import loadavg, machine_info

    info = machine_info()
    targets = [(s, parse_size(s)) for s in args.sizes]

    if args.no_peer:
        peer_python, status = None, "skipped (--no-peer)"
    else:
        peer_python, status = ensure_peer(args.peer_venv, args.peer_python)
    peer = {"python": peer_python, "status": status}
    print(f"JAX-SPH: {status}", flush=True)
    if args.no_pysph:
        pysph = {"python": None, "status": "skipped (--no-pysph)"}
    else:
        pysph = ensure_pysph(args.pysph_venv, args.pysph_limit)
    print(f"PySPH: {pysph['status']}", flush=True)

    backend = "gpu" if info["backend"] == "gpu" else "cpu"
    out = args.out or HERE / "results" / f"side_by_side_{backend}"
    out.parent.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    saved_peer, saved_pysph = peer, pysph
    if args.append and Path(f"{out}.json").exists():
        old = json.loads(Path(f"{out}.json").read_text())
        rows = old["runs"]
        kept = "; its rows are from an earlier run, kept by --append"
        if not peer_python and old.get("peer", {}).get("python"):
            status = old["peer"]["status"].split(kept)[0]
            saved_peer = {**old["peer"], "status": status + kept}
        if not pysph["python"] and old.get("pysph", {}).get("python"):
            status = old["pysph"]["status"].split(kept)[0]
            saved_pysph = {**old["pysph"], "status": status + kept}
        codes = {("jaxmps", s) for s in args.solvers}
        if peer_python:
            codes.add(("jax-sph", "SPH"))
        if pysph["python"]:
            codes.add(("PySPH", "WCSPH"))
        rows = [
            r
            for r in rows
            if not (
                r["size"] in args.sizes
                and r["dtype_requested"] in args.dtypes
                and (r["code"], r.get("solver")) in codes
            )
        ]

    def save():
        info["loadavg_1min_end"] = loadavg()
        ratio_rows = ratios(rows)
        payload = {
            "benchmark": "side_by_side",
            "scene": "dam_break (2-D), 0.146 x 0.292 m column, 0.584 m tank",
            "settings": {
                "sizes": args.sizes,
                "steps": args.steps,
                "repeats": args.repeats,
                "max_timed_s": args.max_timed_s,
                "dtypes": args.dtypes,
                "solvers": args.solvers,
                "rounds": args.rounds,
            },
            "machine": info,
            "peer": saved_peer,
            "pysph": saved_pysph,
            "runs": rows,
            "ratios": ratio_rows,
        }
        Path(f"{out}.json").write_text(json.dumps(payload, indent=2) + "\n")
        md = markdown(info, rows, ratio_rows, saved_peer, saved_pysph, args)
        Path(f"{out}.md").write_text(md)
        return md

    for size, target in targets:
        n = jaxsph_n_across(target)
        matches = {s: jaxmps_match(jaxsph_count(n), s) for s in args.solvers}
        print(
            f"size {size}: JAX-SPH n={n} ({jaxsph_count(n)} particles); jaxmps "
            + ", ".join(f"{s} m={m} ({c})" for s, (m, c) in matches.items()),
            flush=True,
        )
        if pysph["python"]:
            pysph_dx, pysph_n = pysph_match(pysph["python"], target)
            print(f"  PySPH dx={pysph_dx:.4g} m ({pysph_n} particles)", flush=True)
        for dtype in args.dtypes:
            for rnd in range(args.rounds):
                jobs = [("jaxmps", s) for s in args.solvers]
                if peer_python:
                    jobs.append(("jax-sph", "SPH"))
                if pysph["python"] and dtype == "float64":
                    jobs.append(("PySPH", "WCSPH"))
                for code, solver in jobs:
                    t0 = time.perf_counter()
                    if code == "jaxmps":
                        r = run_jaxmps(matches[solver][0], solver, dtype, args)
                    elif code == "PySPH":
                        r = run_pysph(pysph["python"], pysph_dx, args)
                    else:
                        r = run_jaxsph(peer_python, n, dtype, args)
                    r.update(code=code, size=size, dtype_requested=dtype, round=rnd)
                    r.setdefault("solver", solver)
                    r["git_commit"] = info["git_commit"]
                    rows.append(r)
                    if "error" in r:
                        msg = r["error"]
                    else:
                        msg = (
                            f"n={r['capacity']} compile="
                            f"{r['trace_lower_s'] + r['compile_s']:.1f}s run="
                            f"{r['run_s_best']:.2f}s "
                            f"{r['particle_steps_per_s']:.3g} particle-steps/s "
                            f"rss={r['peak_rss_mib']:.0f}MiB"
                        )
                    print(
                        f"  {size} {dtype} {code} {solver}: {msg} "
                        f"[{time.perf_counter() - t0:.0f}s]",
                        flush=True,
                    )
                    save()

    md = save()
    print()
    print(md)
    print(f"wrote {out}.json and {out}.md")


if __name__ == "__main__":
    main()
