"""Step throughput, compile time, memory and forward/gradient cost of `jaxmps`.

Measures, for the 2-D dam break (`jaxmps.scenes.dam_break`) at several resolutions:

* compile time of `jaxmps.simulate` (trace + lower, and XLA compile, separately;
  via `eqx.filter_jit(...).lower(...).compile()`),
* run time of the compiled rollout: best of `--repeats` calls after one untimed
  warm-up call, each ended by `jax.block_until_ready`; reported as ms/step and
  particle-steps/s (capacity x steps / run time),
* mean / max pressure-solve (CG) iterations per step, from `StepInfo` of
  `jaxmps.step` scanned over the same number of steps from the same initial state,
* peak memory: `jax.devices()[0].memory_stats()["peak_bytes_in_use"]` when the
  backend reports it (GPU), else the process peak RSS (`resource.getrusage`), plus
  XLA's own buffer estimate for the compiled rollout (`memory_analysis()`).

and the forward vs reverse-mode gradient run time of a short rollout (default 20
steps at spacing 0.0146; loss = mean final x of the fluid particles, gradient with
respect to all of `Params`).

Each resolution (and the gradient case) runs in a fresh subprocess by default, so
that the peak RSS belongs to that case alone (`--no-isolate` to run in-process).

Usage:
    python benchmarks/step_throughput.py                       # defaults
    python benchmarks/step_throughput.py --spacings 0.0146 0.0073 --steps 100
    python benchmarks/step_throughput.py --grad-steps 40 --grad-spacing 0.0073

Writes `benchmarks/results/step_throughput_<backend>.json` and `.md` (override with
`--out`, a path without extension).
"""

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import fixed_steps, iteration_stats, machine_info, time_compiled
from _common import loadavg as _loadavg

import jaxmps

HERE = Path(__file__).resolve().parent
DEFAULT_SPACINGS = (0.0146, 0.0073, 0.00365)


# ----------------------------------------------------------------------------- helpers


def observe_time(scene, state):
    """Tiny observation (module level, so it does not trigger recompiles)."""
    del scene
    return state.time


def _rss_mib() -> float:
    """Peak resident set size of this process so far [MiB] (Linux: KiB units)."""
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    scale = 1.0 / 1024 if sys.platform != "darwin" else 1.0 / 1024**2
    return r * scale


def _device_peak_mib():
    """Device peak bytes in use [MiB], or None when the backend does not report it."""
    try:
        stats = jax.devices()[0].memory_stats()
    except Exception:  # noqa: BLE001 - some backends raise instead of returning None
        stats = None
    if not stats or "peak_bytes_in_use" not in stats:
        return None
    return stats["peak_bytes_in_use"] / 2**20


def _memory_analysis_mib(compiled: eqx.Module) -> dict | None:
    """XLA's buffer estimate for a compiled executable (equinox `Compiled`)."""
    try:
        ma = compiled.compiled.memory_analysis()
    except Exception:  # noqa: BLE001
        return None
    if ma is None:
        return None
    out = {}
    for name in (
        "temp_size_in_bytes",
        "argument_size_in_bytes",
        "output_size_in_bytes",
        "generated_code_size_in_bytes",
    ):
        value = getattr(ma, name, None)
        if value is not None:
            out[name.replace("_size_in_bytes", "_mib")] = value / 2**20
    return out or None


def _memory_record(baseline_rss: float) -> dict:
    device_peak = _device_peak_mib()
    peak_rss = _rss_mib()
    if device_peak is not None:
        return {
            "peak_mib": device_peak,
            "peak_source": "device memory_stats peak_bytes_in_use",
            "process_peak_rss_mib": peak_rss,
            "baseline_rss_mib": baseline_rss,
        }
    return {
        "peak_mib": peak_rss,
        "peak_source": "process peak RSS (resource.getrusage ru_maxrss)",
        "process_peak_rss_mib": peak_rss,
        "baseline_rss_mib": baseline_rss,
    }


# ----------------------------------------------------------------------------- workers


def throughput_case(spacing: float, n_steps: int, repeats: int) -> dict:
    case = fixed_steps(jaxmps.scenes.dam_break(spacing=spacing))
    scene, params, state = case.scene, case.params, case.state
    jax.block_until_ready((params, state))
    n_fluid = int(jnp.sum(state.kind == int(jaxmps.Kind.FLUID)))
    baseline_rss = _rss_mib()

    args = (scene, params, state, n_steps, None, observe_time)
    timed = time_compiled(jaxmps.lower_simulate, *args, repeats=repeats, throw=False)
    traj, compiled = timed.output, timed.compiled
    t_lower, t_compile = timed.trace_lower_s, timed.compile_s
    best, times = timed.run_s_best, timed.run_s_all
    result = str(traj.result)
    rollout_ok = bool(traj.result == jaxmps.Result.successful)
    simulated = float(traj.state.time)

    # Pressure-solve iterations: same steps, read from StepInfo (separate compile,
    # not part of the timings above).
    it_result, iters, converged = jax.block_until_ready(
        iteration_stats(scene, params, state, n_steps)
    )
    iters = np.asarray(iters)
    record = {
        "spacing": spacing,
        "capacity": int(scene.capacity),
        "n_fluid": n_fluid,
        "n_steps": n_steps,
        "dt": float(params.dt),
        "simulated_time": simulated,
        "trace_lower_s": t_lower,
        "compile_s": t_compile,
        "run_s_best": best,
        "run_s_all": times,
        "ms_per_step": 1e3 * best / n_steps,
        "particle_steps_per_s": scene.capacity * n_steps / best,
        "pressure_iterations_mean": float(iters.mean()),
        "pressure_iterations_max": int(iters.max()),
        "pressure_converged_fraction": float(np.asarray(converged).mean()),
        "result": result,
        "rollout_successful": rollout_ok,
        "iteration_run_result": str(it_result),
        "xla_memory_analysis": _memory_analysis_mib(compiled),
    }
    record.update(_memory_record(baseline_rss))
    record["loadavg_1min_end"] = _loadavg()
    return record


def fluid_mean_x(params, scene, state, n_steps: int, save_every: int):
    traj = jaxmps.simulate(
        scene, params, state, n_steps, save_every, observe_time, throw=False
    )
    fluid = traj.state.kind == int(jaxmps.Kind.FLUID)
    x = traj.state.position[:, 0]
    return jnp.sum(jnp.where(fluid, x, 0.0)) / jnp.sum(fluid)


forward_fn = eqx.filter_jit(fluid_mean_x)
gradient_fn = eqx.filter_jit(eqx.filter_grad(fluid_mean_x))


def gradient_case(spacing: float, n_steps: int, repeats: int) -> dict:
    case = fixed_steps(jaxmps.scenes.dam_break(spacing=spacing))
    scene, params, state = case.scene, case.params, case.state
    save_every = max(1, int(round(np.sqrt(n_steps))))
    while n_steps % save_every:
        save_every -= 1
    baseline_rss = _rss_mib()
    args = (params, scene, state, n_steps, save_every)

    fwd = time_compiled(forward_fn.lower, *args, repeats=repeats)
    fwd_lower, fwd_compile, loss = fwd.trace_lower_s, fwd.compile_s, fwd.output
    fwd_best, fwd_times = fwd.run_s_best, fwd.run_s_all
    grd = time_compiled(gradient_fn.lower, *args, repeats=repeats)
    grd_lower, grd_compile, grads = grd.trace_lower_s, grd.compile_s, grd.output
    grd_best, grd_times = grd.run_s_best, grd.run_s_all

    leaves = jax.tree_util.tree_leaves(grads)
    finite = all(bool(jnp.all(jnp.isfinite(g))) for g in leaves)
    grads_out = {
        name: np.asarray(getattr(grads, name)).tolist()
        for name in ("density", "viscosity", "gravity", "dt", "beta")
        if hasattr(grads, name)
    }
    record = {
        "spacing": spacing,
        "capacity": int(scene.capacity),
        "n_steps": n_steps,
        "save_every": save_every,
        "checkpoint": True,
        "loss": float(loss),
        "forward_trace_lower_s": fwd_lower,
        "forward_compile_s": fwd_compile,
        "forward_run_s_best": fwd_best,
        "forward_run_s_all": fwd_times,
        "gradient_trace_lower_s": grd_lower,
        "gradient_compile_s": grd_compile,
        "gradient_run_s_best": grd_best,
        "gradient_run_s_all": grd_times,
        "gradient_forward_ratio": grd_best / fwd_best,
        "gradient_finite": finite,
        "gradient": grads_out,
        "forward_xla_memory_analysis": _memory_analysis_mib(fwd),
        "gradient_xla_memory_analysis": _memory_analysis_mib(grd),
    }
    record.update(_memory_record(baseline_rss))
    record["loadavg_1min_end"] = _loadavg()
    return record


# ----------------------------------------------------------------------------- driver


def _run_worker(kind: str, spacing: float, steps: int, repeats: int, isolate: bool):
    if not isolate:
        fn = throughput_case if kind == "throughput" else gradient_case
        return fn(spacing, steps, repeats)
    cmd = [
        sys.executable,
        __file__,
        "--worker",
        kind,
        "--worker-spacing",
        repr(spacing),
        "--worker-steps",
        str(steps),
        "--repeats",
        str(repeats),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr)
        raise RuntimeError(f"worker {kind} spacing={spacing} failed")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _fmt(x):
    return "?" if x is None else f"{x:.2f}"


def markdown(info: dict, rows: list[dict], grad: dict | None, args) -> str:
    tag = "GPU" if info["backend"] == "gpu" else f"CPU ({info['cpu_usable']} cores)"
    lines = [
        f"# Step throughput: 2-D dam break, {tag}",
        "",
        f"- machine: {info['platform']}, {info['cpu_model']}, "
        f"{info['cpu_usable']} usable / {info['cpu_count']} CPUs",
        f"- device: {info['device']}; jax {info['jax']} (jaxlib {info['jaxlib']}), "
        f"equinox {info['equinox']}, jaxmps {info['jaxmps']}, python {info['python']}",
        f"- dtype: {info['dtype']} (jax_enable_x64={info['jax_enable_x64']}); "
        f"git {info['git_commit']}"
        + (" (uncommitted changes)" if info["git_dirty_tracked"] else ""),
        f"- 1-min load average: {_fmt(info.get('loadavg_1min_start'))} at start, "
        f"{_fmt(info.get('loadavg_1min_end'))} at end (> core count means other "
        "processes competed for the CPU)",
        f"- {args.steps} steps per resolution; run time = best of {args.repeats} calls "
        "after one untimed warm-up call; the compiling call is never timed as run "
        "time.",
        "",
        "| spacing [m] | particles (fluid) | compile [s] (trace+lower / XLA) "
        "| run [s] | ms/step | particle-steps/s | CG it./step (mean, max) "
        "| peak mem [MiB] | XLA temp [MiB] | result |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        temp = (r.get("xla_memory_analysis") or {}).get("temp_mib")
        lines.append(
            f"| {r['spacing']:g} | {r['capacity']} ({r['n_fluid']}) "
            f"| {r['trace_lower_s'] + r['compile_s']:.2f} "
            f"({r['trace_lower_s']:.2f} / {r['compile_s']:.2f}) "
            f"| {r['run_s_best']:.3f} | {r['ms_per_step']:.2f} "
            f"| {r['particle_steps_per_s']:.3g} "
            f"| {r['pressure_iterations_mean']:.1f}, {r['pressure_iterations_max']} "
            f"| {r['peak_mib']:.0f} "
            f"| {'-' if temp is None else f'{temp:.1f}'} "
            f"| {'ok' if r['rollout_successful'] else r['result']} |"
        )
    if rows:
        lines += [
            "",
            f"Peak memory source: {rows[0]['peak_source']} of a fresh process "
            "per resolution"
            if args.isolate
            else f"Peak memory source: {rows[0]['peak_source']} (cumulative, one "
            "process)",
            "",
        ]
    if grad is not None:
        g = grad
        lines += [
            f"## Forward vs gradient: {g['n_steps']} steps at spacing {g['spacing']:g} "
            f"({g['capacity']} particles)",
            "",
            "Loss = mean final x of the fluid particles; reverse-mode gradient w.r.t. "
            f"all of `Params` (`eqx.filter_grad`); `simulate(..., save_every="
            f"{g['save_every']}, checkpoint=True)`. Compile excluded; best of "
            f"{args.grad_repeats}.",
            "",
            "| | compile [s] (trace+lower / XLA) | run [s] |",
            "|---|---|---|",
            f"| forward | {g['forward_trace_lower_s'] + g['forward_compile_s']:.2f} "
            f"({g['forward_trace_lower_s']:.2f} / {g['forward_compile_s']:.2f}) "
            f"| {g['forward_run_s_best']:.4f} |",
            f"| gradient | {g['gradient_trace_lower_s'] + g['gradient_compile_s']:.2f} "
            f"({g['gradient_trace_lower_s']:.2f} / {g['gradient_compile_s']:.2f}) "
            f"| {g['gradient_run_s_best']:.4f} |",
            "",
            f"**gradient / forward run-time ratio: {g['gradient_forward_ratio']:.2f}** "
            f"(gradient finite: {g['gradient_finite']}; peak memory "
            f"{g['peak_mib']:.0f} MiB)",
            "",
        ]
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacings", type=float, nargs="+", default=list(DEFAULT_SPACINGS))
    p.add_argument("--steps", type=int, default=200, help="steps per resolution")
    p.add_argument("--repeats", type=int, default=3, help="timed calls (best taken)")
    p.add_argument("--grad-spacing", type=float, default=0.0146)
    p.add_argument("--grad-steps", type=int, default=20)
    p.add_argument(
        "--grad-repeats",
        type=int,
        default=5,
        help="timed calls of the (cheap) forward/gradient case",
    )
    p.add_argument("--no-grad", action="store_true", help="skip forward vs gradient")
    p.add_argument(
        "--no-isolate",
        dest="isolate",
        action="store_false",
        help="run every case in this process (peak RSS is then cumulative)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output path without extension "
        "(default benchmarks/results/step_throughput_<cpu|gpu>)",
    )
    p.add_argument(
        "--worker", choices=("throughput", "gradient"), help=argparse.SUPPRESS
    )
    p.add_argument("--worker-spacing", type=float, help=argparse.SUPPRESS)
    p.add_argument("--worker-steps", type=int, help=argparse.SUPPRESS)
    args = p.parse_args(argv)

    if args.worker:
        fn = throughput_case if args.worker == "throughput" else gradient_case
        print(json.dumps(fn(args.worker_spacing, args.worker_steps, args.repeats)))
        return

    info = machine_info()
    print(
        f"backend={info['backend']} device={info['device']} dtype={info['dtype']} "
        f"cpus={info['cpu_usable']}",
        flush=True,
    )
    rows = []
    for spacing in args.spacings:
        t0 = time.perf_counter()
        r = _run_worker("throughput", spacing, args.steps, args.repeats, args.isolate)
        rows.append(r)
        print(
            f"spacing={spacing:g}: n={r['capacity']} compile={r['compile_s']:.2f}s "
            f"run={r['run_s_best']:.3f}s ({r['ms_per_step']:.2f} ms/step) "
            f"CG={r['pressure_iterations_mean']:.1f} [{time.perf_counter() - t0:.0f}s "
            "wall]",
            flush=True,
        )
    grad = None
    if not args.no_grad:
        grad = _run_worker(
            "gradient",
            args.grad_spacing,
            args.grad_steps,
            args.grad_repeats,
            args.isolate,
        )
        print(
            f"gradient: forward={grad['forward_run_s_best']:.4f}s "
            f"gradient={grad['gradient_run_s_best']:.4f}s "
            f"ratio={grad['gradient_forward_ratio']:.2f}",
            flush=True,
        )

    info["loadavg_1min_end"] = _loadavg()
    md = markdown(info, rows, grad, args)
    print()
    print(md)
    backend = "gpu" if info["backend"] == "gpu" else "cpu"
    out = args.out or HERE / "results" / f"step_throughput_{backend}"
    out.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "benchmark": "step_throughput",
        "scene": "dam_break (2-D)",
        "settings": {
            "spacings": args.spacings,
            "steps": args.steps,
            "repeats": args.repeats,
            "grad_spacing": args.grad_spacing,
            "grad_steps": args.grad_steps,
            "grad_repeats": args.grad_repeats,
            "isolated_processes": args.isolate,
        },
        "machine": info,
        "throughput": rows,
        "gradient": grad,
    }
    Path(f"{out}.json").write_text(json.dumps(payload, indent=2) + "\n")
    Path(f"{out}.md").write_text(md)
    print(f"wrote {out}.json and {out}.md")


if __name__ == "__main__":
    main()
