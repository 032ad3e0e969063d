"""Memory of reverse-mode gradients of long rollouts, with and without checkpointing.

`jaxmps.simulate` runs two nested `lax.scan`s: an outer one over `n_steps / save_every`
blocks and an inner one over the `save_every` steps of a block. With
`checkpoint=True` each block is wrapped in `jax.checkpoint`, so the backward pass
stores only the block-boundary states (n_steps / save_every of them) plus the
residuals of the one block being re-run (save_every steps; the neighbour search is
recomputed); with save_every ~ sqrt(n_steps) the memory grows like sqrt(n_steps).
With `checkpoint="steps"` each step is checkpointed as well, so the block being
re-run stores save_every states instead of save_every steps' residuals (tens of
(particles, slots) arrays each), for one more forward evaluation of every step.
With `checkpoint=False` the residuals of every step are stored: memory ~ n_steps.

For each T in `--steps` and checkpoint in (True, "steps", False), this script measures

1. XLA's static buffer estimate (`Compiled.memory_analysis()`: temp, argument and
   output bytes) of the compiled *gradient* program and of the forward program; this
   needs only compilation, so it is available where running would exhaust memory;
2. where the static gradient estimate is below `--max-run-gib` and
   T <= `--run-max-steps`:
   the process peak RSS of running the gradient in a fresh subprocess (minus the
   baseline after building the case, and minus the resident size just before the
   first gradient call), and the forward and gradient run times (compile excluded,
   best of `--repeats` calls of the compiled program after an untimed one, each
   ended by `jax.block_until_ready`: `_common.time_calls`), giving the gradient /
   forward run-time ratio;
3. the log-log slope of memory vs T for each checkpoint setting.

Scene: `jaxmps.scenes.hydrostatic` (still water; stays calm for long rollouts), by
default spacing 0.005 m, width 0.3 m, depth 0.2 m (2898 particles incl. walls, 2400
fluid). `--scene dam_break` uses the dam break instead (it leaves its validated range
after ~0.3 s simulated, so long rollouts may end with a failure Result; the memory
numbers are still meaningful while finite).

Loss: mean final x of the fluid particles + 1e-6 * mean final fluid pressure; gradient
with respect to all of `Params` (`eqx.filter_grad`). The observe function returns only
the time, so no frames are stored.

Usage:
    python benchmarks/gradient_memory.py                        # defaults
    python benchmarks/gradient_memory.py --no-run               # static estimates only
    python benchmarks/gradient_memory.py --steps 250 1000 --spacing 0.0065

Writes `benchmarks/results/gradient_memory_<backend>.{json,md,png}` (override with
`--out`, a path without extension).
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import compile_timed, loadavg, machine_info, time_calls

import jaxmps

HERE = Path(__file__).resolve().parent
# `simulate(checkpoint=...)` settings measured: key in the JSON summary, label, colour.
MODES = {
    True: ("checkpoint", "blocks", "C0"),
    "steps": ("checkpoint_steps", "blocks + steps", "C2"),
    False: ("no_checkpoint", "none", "C3"),
}
ORDER = {mode: i for i, mode in enumerate(MODES)}


def _same(a, b) -> bool:
    """Equal checkpoint settings (True == 1 but True is not "steps")."""
    return type(a) is type(b) and a == b


GIB = 2**30
MIB = 2**20


def observe_time(scene, state):
    """Tiny observation (module level, so it does not trigger recompiles)."""
    del scene
    return state.time


def peak_rss_bytes() -> int:
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r * (1 if sys.platform == "darwin" else 1024)


def current_rss_bytes() -> int | None:
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE")


def choose_save_every(n_steps: int) -> int:
    """Divisor d of n_steps minimising n_steps / d + d (ties: the smaller d)."""
    divisors = [d for d in range(1, n_steps + 1) if n_steps % d == 0]
    return min(divisors, key=lambda d: (n_steps / d + d, d))


def build_case(
    scene_name: str, spacing: float, width: float, depth: float, stepping: str
):
    """The case, with fixed steps of the scene's largest step ("fixed") or the
    scene's default adaptive steps ("adaptive")."""
    if scene_name == "hydrostatic":
        build = lambda **s: jaxmps.scenes.hydrostatic(  # noqa: E731
            spacing=spacing, width=width, depth=depth, **s
        )
    else:
        build = lambda **s: jaxmps.scenes.dam_break(spacing=spacing, **s)  # noqa: E731
    case = build()
    return build(dt=float(case.params.dt)) if stepping == "fixed" else case


def loss_fn(params, scene, state, n_steps, save_every, checkpoint):
    traj = jaxmps.simulate(
        scene,
        params,
        state,
        n_steps,
        save_every,
        observe_time,
        throw=False,
        checkpoint=checkpoint,
    )
    fluid = traj.state.kind == int(jaxmps.Kind.FLUID)
    n = jnp.sum(fluid)
    x = jnp.sum(jnp.where(fluid, traj.state.position[:, 0], 0.0)) / n
    p = jnp.sum(jnp.where(fluid, traj.state.pressure, 0.0)) / n
    return x + 1e-6 * p, traj.result


forward_fn = eqx.filter_jit(loss_fn)
gradient_fn = eqx.filter_jit(eqx.filter_grad(loss_fn, has_aux=True))


def memory_analysis(compiled) -> dict | None:
    try:
        ma = compiled.compiled.memory_analysis()
    except Exception:  # noqa: BLE001
        return None
    if ma is None:
        return None
    out = {}
    for name in ("temp", "argument", "output", "alias", "generated_code"):
        value = getattr(ma, f"{name}_size_in_bytes", None)
        if value is not None:
            out[f"{name}_bytes"] = int(value)
    out["total_bytes"] = sum(
        out.get(f"{k}_bytes", 0) for k in ("temp", "argument", "output")
    ) - out.get("alias_bytes", 0)
    return out


def lower_compile(fn, *args):
    """The compiled program and its trace, lower and compile time [s]."""
    compiled, trace_lower_s, compile_s = compile_timed(fn.lower, *args)
    return compiled, trace_lower_s + compile_s


def worker(cfg: dict) -> dict:
    case = build_case(
        cfg["scene"], cfg["spacing"], cfg["width"], cfg["depth"], cfg["stepping"]
    )
    scene, params, state = case.scene, case.params, case.state
    jax.block_until_ready((params, state))
    baseline_peak = peak_rss_bytes()
    n_steps, save_every, ckpt = cfg["n_steps"], cfg["save_every"], cfg["checkpoint"]
    args = (params, scene, state, n_steps, save_every, ckpt)

    grd, grd_compile_s = lower_compile(gradient_fn, *args)
    fwd, fwd_compile_s = lower_compile(forward_fn, *args)
    rec = {
        **cfg,
        "capacity": int(scene.capacity),
        "n_fluid": int(jnp.sum(state.kind == int(jaxmps.Kind.FLUID))),
        "dt": float(params.dt),
        "simulated_time": float(params.dt) * n_steps,
        "gradient_compile_s": grd_compile_s,
        "forward_compile_s": fwd_compile_s,
        "gradient_xla": memory_analysis(grd),
        "forward_xla": memory_analysis(fwd),
        "baseline_peak_rss_bytes": baseline_peak,
        "compiled_peak_rss_bytes": peak_rss_bytes(),
        "ran": False,
    }
    static = (rec["gradient_xla"] or {}).get("total_bytes", 0)
    if not cfg["run"]:
        rec["skip_reason"] = "--no-run"
        return rec
    if n_steps > cfg["run_max_steps"]:
        rec["skip_reason"] = f"T > --run-max-steps={cfg['run_max_steps']}"
        return rec
    if static > cfg["max_run_gib"] * GIB:
        rec["skip_reason"] = f"static estimate > {cfg['max_run_gib']} GiB"
        return rec

    before_run_rss = current_rss_bytes()
    before_run_peak = peak_rss_bytes()
    (grads, g_result), _, g_times = time_calls(lambda: grd(*args), cfg["repeats"])
    grad_peak = peak_rss_bytes()
    (loss, f_result), _, f_times = time_calls(lambda: fwd(*args), cfg["repeats"])
    leaves = [x for x in jax.tree_util.tree_leaves(grads) if eqx.is_array(x)]
    rec.update(
        ran=True,
        before_run_rss_bytes=before_run_rss,
        before_run_peak_rss_bytes=before_run_peak,
        gradient_peak_rss_bytes=grad_peak,
        final_peak_rss_bytes=peak_rss_bytes(),
        rss_over_baseline_bytes=grad_peak - baseline_peak,
        rss_over_pre_run_bytes=(
            None if before_run_rss is None else grad_peak - before_run_rss
        ),
        gradient_run_s_all=g_times,
        forward_run_s_all=f_times,
        gradient_run_s=min(g_times),
        forward_run_s=min(f_times),
        gradient_forward_ratio=min(g_times) / min(f_times),
        loss=float(loss),
        result=str(f_result),
        rollout_successful=bool(f_result == jaxmps.Result.successful),
        gradient_finite=all(bool(jnp.all(jnp.isfinite(g))) for g in leaves),
        grad_dt=float(grads.dt) if eqx.is_array(getattr(grads, "dt", None)) else None,
        loadavg_1min_end=loadavg(),
    )
    return rec


def run_isolated(cfg: dict) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", json.dumps(cfg)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr[-4000:])
        return {**cfg, "error": f"worker exited with {proc.returncode}"}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def slope(ts, values):
    pts = [(t, v) for t, v in zip(ts, values) if v is not None and v > 0]
    if len(pts) < 2:
        return None
    x = np.log([p[0] for p in pts])
    y = np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def summarise(rows: list[dict]) -> dict:
    out = {}
    for ckpt, (key, _, _) in MODES.items():
        rs = sorted(
            (r for r in rows if _same(r["checkpoint"], ckpt) and "error" not in r),
            key=lambda r: r["n_steps"],
        )
        ts = [r["n_steps"] for r in rs]
        g = [(r.get("gradient_xla") or {}) for r in rs]
        ran = [r for r in rs if r.get("ran")]
        out[key] = {
            "T": ts,
            "slope_static_total": slope(ts, [x.get("total_bytes") for x in g]),
            "slope_static_temp": slope(ts, [x.get("temp_bytes") for x in g]),
            "T_run": [r["n_steps"] for r in ran],
            "slope_rss_over_baseline": slope(
                [r["n_steps"] for r in ran],
                [r["rss_over_baseline_bytes"] for r in ran],
            ),
            "slope_rss_over_pre_run": slope(
                [r["n_steps"] for r in ran],
                [r.get("rss_over_pre_run_bytes") for r in ran],
            ),
        }
    return out


def _mib(b):
    return "-" if b is None else f"{b / MIB:,.1f}"


def _s(x, fmt=".2f"):
    return "-" if x is None else format(x, fmt)


def markdown(info: dict, rows: list[dict], summary: dict, args) -> str:
    r0 = next((r for r in rows if "capacity" in r), {})
    tag = "GPU" if info["backend"] == "gpu" else f"CPU ({info['cpu_usable']} cores)"
    scene_desc = (
        f"`hydrostatic(spacing={args.spacing}, width={args.width}, depth={args.depth})`"
        if args.scene == "hydrostatic"
        else f"`dam_break(spacing={args.spacing})`"
    )
    lines = [
        f"# Gradient memory vs rollout length, {tag}",
        "",
        f"- machine: {info['platform']}, {info['cpu_model']}, "
        f"{info['cpu_usable']} usable CPUs; device {info['device']}",
        f"- jax {info['jax']} (jaxlib {info['jaxlib']}), equinox {info['equinox']}, "
        f"jaxmps {info['jaxmps']}, python {info['python']}, "
        f"x64={info['jax_enable_x64']}; git {info['git_commit']}; {info['date']}",
        f"- 1-min load average: {_s(info.get('loadavg_1min_start'))} at start, "
        f"{_s(info.get('loadavg_1min_end'))} at end",
        f"- scene: {scene_desc}: {r0.get('capacity', '?')} particles "
        f"({r0.get('n_fluid', '?')} fluid), dt = {_s(r0.get('dt'), '.3g')} s",
        "- loss: mean final fluid x + 1e-6 * mean final fluid pressure; "
        "`eqx.filter_grad` w.r.t. all of `Params`; observe = time only",
        "- save_every: divisor of T minimising T/save_every + save_every (~sqrt(T)); "
        "the same save_every is used without checkpointing",
        f"- runs: each (T, checkpoint) in a fresh subprocess; run time = best of "
        f"{args.repeats} calls of the compiled program after an untimed one "
        "(compile excluded, `block_until_ready`); runs skipped where T > "
        f"{args.run_max_steps} or the static estimate > {args.max_run_gib} GiB",
        "",
        "XLA static = `Compiled.memory_analysis()` (temp + argument + output - alias). "
        "Peak RSS over baseline = process `ru_maxrss` after the gradient calls minus "
        "`ru_maxrss` after building the case (includes the compiler's own peak); "
        "over pre-run = minus the resident size just before the first gradient call "
        "(after compiling both programs).",
        "",
        "| T | checkpoint | save_every | simulated [s] | grad XLA temp [MiB] "
        "| grad XLA total [MiB] | fwd XLA temp [MiB] | fwd XLA total [MiB] "
        "| peak RSS over baseline [MiB] | over pre-run [MiB] | forward [s] "
        "| gradient [s] | grad/fwd | result |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in sorted(rows, key=lambda r: (ORDER[r["checkpoint"]], r["n_steps"])):
        if "error" in r:
            lines.append(
                f"| {r['n_steps']} | {r['checkpoint']} | {r['save_every']} "
                f"| | | | | | | | | | | {r['error']} |"
            )
            continue
        g, f = r.get("gradient_xla") or {}, r.get("forward_xla") or {}
        if r.get("ran"):
            res = "ok" if r["rollout_successful"] else r["result"]
            if not r["gradient_finite"]:
                res += ", grad NOT finite"
            run_cols = (
                f"| {_mib(r['rss_over_baseline_bytes'])} "
                f"| {_mib(r.get('rss_over_pre_run_bytes'))} "
                f"| {r['forward_run_s']:.2f} | {r['gradient_run_s']:.2f} "
                f"| {r['gradient_forward_ratio']:.2f} | {res} |"
            )
        else:
            run_cols = f"| - | - | - | - | - | not run ({r.get('skip_reason')}) |"
        lines.append(
            f"| {r['n_steps']} | {r['checkpoint']} | {r['save_every']} "
            f"| {r['simulated_time']:.2f} "
            f"| {_mib(g.get('temp_bytes'))} | {_mib(g.get('total_bytes'))} "
            f"| {_mib(f.get('temp_bytes'))} | {_mib(f.get('total_bytes'))} " + run_cols
        )
    lines += [
        "",
        "Log-log slope of memory vs T (least squares over the T values available):",
        "",
        "| checkpoint | grad XLA total | grad XLA temp | peak RSS over baseline "
        "| peak RSS over pre-run |",
        "|---|---|---|---|---|",
    ]
    for ckpt, (key, _, _) in MODES.items():
        s = summary[key]
        label = ckpt
        lines.append(
            f"| {label} | {_s(s['slope_static_total'])} | {_s(s['slope_static_temp'])} "
            f"| {_s(s['slope_rss_over_baseline'])} (T={s['T_run']}) "
            f"| {_s(s['slope_rss_over_pre_run'])} |"
        )
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for ckpt, (_, name, colour) in MODES.items():
        rs = sorted(
            (r for r in rows if _same(r["checkpoint"], ckpt) and "error" not in r),
            key=lambda r: r["n_steps"],
        )
        if not rs:
            continue
        label = f"checkpoint {name}"
        ts = [r["n_steps"] for r in rs]
        ax.loglog(
            ts,
            [(r["gradient_xla"] or {}).get("total_bytes", np.nan) / MIB for r in rs],
            "o-",
            color=colour,
            label=f"{label}: XLA static (gradient)",
        )
        ran = [r for r in rs if r.get("ran")]
        if ran:
            ax.loglog(
                [r["n_steps"] for r in ran],
                [(r.get("rss_over_pre_run_bytes") or np.nan) / MIB for r in ran],
                "s--",
                color=colour,
                mfc="none",
                label=f"{label}: peak RSS over pre-run RSS",
            )
    ts = sorted({r["n_steps"] for r in rows})
    if ts:
        ref = [
            r
            for r in rows
            if _same(r["checkpoint"], True)
            and r["n_steps"] == ts[0]
            and "error" not in r
        ]
        if ref and ref[0].get("gradient_xla"):
            m0 = ref[0]["gradient_xla"]["total_bytes"] / MIB
            ax.loglog(
                ts, [m0 * (t / ts[0]) ** 0.5 for t in ts], "k:", lw=1, label="~ T^0.5"
            )
        ref = [
            r
            for r in rows
            if _same(r["checkpoint"], False)
            and r["n_steps"] == ts[0]
            and "error" not in r
        ]
        if ref and ref[0].get("gradient_xla"):
            m0 = ref[0]["gradient_xla"]["total_bytes"] / MIB
            ax.loglog(ts, [m0 * t / ts[0] for t in ts], "k--", lw=1, label="~ T^1")
    ax.set_xlabel("rollout steps T")
    ax.set_ylabel("memory [MiB]")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--steps", type=int, nargs="+", default=[250, 1000, 4000])
    p.add_argument(
        "--scene", choices=("hydrostatic", "dam_break"), default="hydrostatic"
    )
    p.add_argument("--spacing", type=float, default=0.005)
    p.add_argument(
        "--stepping",
        choices=("fixed", "adaptive"),
        default="fixed",
        help="fixed steps (a scan per save) or the scenes' default adaptive steps "
        "(a checkpointed while loop per save); results go to "
        "gradient_memory[_adaptive]_<backend>",
    )
    p.add_argument("--width", type=float, default=0.3, help="hydrostatic tank width")
    p.add_argument("--depth", type=float, default=0.2, help="hydrostatic water depth")
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--no-run", action="store_true", help="static estimates only")
    p.add_argument(
        "--run-max-steps",
        type=int,
        default=1000,
        help="run (time, measure RSS) only T up to this; larger T: static only",
    )
    p.add_argument("--max-run-gib", type=float, default=12.0)
    p.add_argument(
        "--checkpoint",
        choices=("all", "both", "on", "steps", "off"),
        default="all",
        help="which simulate(checkpoint=...) settings to measure: on = True (blocks), "
        "steps = 'steps' (blocks and steps), off = False; both = on and off",
    )
    p.add_argument(
        "--merge",
        action="store_true",
        help="merge into the existing JSON at --out (replacing equal (T, checkpoint))",
    )
    p.add_argument("--out", type=str, default=None)
    p.add_argument("--worker", type=str, help=argparse.SUPPRESS)
    args = p.parse_args(argv)

    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return

    info = machine_info()
    backend = "gpu" if info["backend"] == "gpu" else "cpu"
    name = "gradient_memory" + ("_adaptive" if args.stepping == "adaptive" else "")
    out = Path(args.out) if args.out else HERE / "results" / f"{name}_{backend}"
    out.parent.mkdir(parents=True, exist_ok=True)
    settings = {
        "all": (True, "steps", False),
        "both": (True, False),
        "on": (True,),
        "steps": ("steps",),
        "off": (False,),
    }[args.checkpoint]
    old_rows = []
    if args.merge and Path(f"{out}.json").exists():
        old_rows = json.loads(Path(f"{out}.json").read_text())["rows"]
    rows = []
    for ckpt in settings:
        for t in args.steps:
            cfg = {
                "scene": args.scene,
                "stepping": args.stepping,
                "spacing": args.spacing,
                "width": args.width,
                "depth": args.depth,
                "n_steps": t,
                "save_every": choose_save_every(t),
                "checkpoint": ckpt,
                "run": not args.no_run,
                "run_max_steps": args.run_max_steps,
                "max_run_gib": args.max_run_gib,
                "repeats": args.repeats,
            }
            t0 = time.perf_counter()
            r = run_isolated(cfg)
            r["wall_s"] = time.perf_counter() - t0
            rows.append(r)
            g = (r.get("gradient_xla") or {}).get("total_bytes")
            print(
                f"T={t} checkpoint={ckpt} save_every={cfg['save_every']}: "
                f"grad XLA total {_mib(g)} MiB, ran={r.get('ran')}, "
                f"ratio={_s(r.get('gradient_forward_ratio'))}, "
                f"rss+={_mib(r.get('rss_over_baseline_bytes'))} MiB "
                f"({r['wall_s']:.0f} s)",
                flush=True,
            )
    info["loadavg_1min_end"] = loadavg()
    new_keys = {(r["n_steps"], str(r["checkpoint"])) for r in rows}
    rows = [
        r for r in old_rows if (r["n_steps"], str(r["checkpoint"])) not in new_keys
    ] + rows
    summary = summarise(rows)
    Path(f"{out}.json").write_text(
        json.dumps(
            {"machine": info, "args": vars(args), "rows": rows, "slopes": summary},
            indent=2,
        )
    )
    Path(f"{out}.md").write_text(markdown(info, rows, summary, args))
    plot(rows, Path(f"{out}.png"), f"Gradient memory vs T ({args.scene}, {backend})")
    print(Path(f"{out}.md").read_text())


if __name__ == "__main__":
    main()
