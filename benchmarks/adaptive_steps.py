"""Adaptive against fixed time steps: cost per simulated second, accuracy, and the
dt a dam break takes.

Three measurements, each rollout compiled apart from running (`jaxmps.lower_simulate`
then `.compile()`; compile time reported separately) and run once
(`_common.time_compiled` with `repeats=0`: these runs are long):

1. **Runs to 2 s at defaults.** The dam break of a widely used experiment geometry
   (a 0.6 m x 0.3 m column in a 1.61 m tank, Lobovsky et al. 2014), at l0 = 1 cm
   and with every other setting default, and the same geometry 2x larger and 2x
   smaller (l0 = 1 cm in all three), saved every 0.01 s. Adaptive (the default)
   and fixed at the scene's own dt (the largest step of the adaptive run), and
   then fixed at halved dt until a run reaches 2 s: the best hand-picked fixed dt.
   Reported: where each run stopped and why, steps, wall time per simulated
   second, and at each save the limits of `jaxmps.time_step_limits` (which one
   sets dt, over time), with the dt of the steps behind every save
   (`Trajectory.steps`).
2. **Accuracy at equal settings.** The default dam break (Koshizuka & Oka's 0.146 m
   x 0.292 m column, l0 = 7.3 mm) against Martin & Moyce 1952 (surge front Z at
   T = 1, 1.5, 2, 2.5; tests/data); the hydrostatic tank's bottom-pressure noise
   (0.2 m x 0.2 m, l0 = 1 cm, t = 0.5 ... 1 s); the standing wave's period against
   linear theory (0.4 m pool, 0.2 m deep, A = 2 cm, l0 = 1 cm, 1.6 s). Adaptive
   against fixed at the same largest step.
3. The distribution of dt over the 1.61 m dam break (plot).

Usage:
    python benchmarks/adaptive_steps.py            # everything (~20 min, 2 CPU)
    python benchmarks/adaptive_steps.py --quick    # l0 = 2 cm, to 1 s
    python benchmarks/adaptive_steps.py --x64 --parts runs --scheme standard_ds \
        --merge --out benchmarks/results/adaptive_steps_schemes_cpu
                                                   # adaptive runs of one scheme
                                                   # (or --solver explicit) only

Writes `benchmarks/results/adaptive_steps_<backend>.{json,md,png}`.
"""

import argparse
import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from _common import machine_info, result_name, time_compiled

import jaxmps

ROOT = Path(__file__).resolve().parent
DATA = ROOT.parent / "tests" / "data"
G = 9.81
T_CHECK = (1.0, 1.5, 2.0, 2.5)
LOBOVSKY = dict(column_width=0.6, column_height=0.3, tank_length=1.61)


def _observer(case):
    probes = tuple(case.probes)

    def observe(scene, state):
        out = {"time": state.time}
        for probe in probes:
            out[probe.name] = probe(scene, state)
        if scene.time_step is not None:
            limits = jaxmps.time_step_limits(scene, case.params, state)
            out.update({f"limit_{k}": v for k, v in limits.items()})
        return out

    return observe


def rollout(case, t_end: float, save_every: float) -> dict:
    """Run `case` to `t_end`, saving every `save_every`; the record of the run."""
    dtype = case.state.time.dtype
    times = jnp.asarray(np.arange(1, round(t_end / save_every) + 1) * save_every, dtype)
    timed = time_compiled(
        jaxmps.lower_simulate,
        case.scene,
        case.params,
        case.state,
        times=times,
        observe=_observer(case),
        throw=False,
        repeats=0,
    )
    tr = timed.output
    saved = {k: np.asarray(v) for k, v in tr.saved.items()}
    history = {
        k: np.asarray(getattr(tr.steps, k))
        for k in ("accepted", "rejected", "dt_min", "dt_max")
    }
    reached = float(tr.state.time)
    steps = int(tr.state.step)
    run_s = timed.warmup_s
    adaptive = case.scene.time_step is not None
    record = {
        "adaptive": adaptive,
        "dt": float(case.params.dt),
        "capacity": int(case.scene.capacity),
        "n_fluid": int(
            np.sum(np.asarray(case.state.active) & (np.asarray(case.state.kind) == 0))
        ),
        "result": result_name(tr.result),
        "reached_s": reached,
        "steps": steps,
        "rejected": int(history["rejected"].sum()),
        "escaped": int(tr.state.escaped),
        "compile_s": timed.trace_lower_s + timed.compile_s,
        "run_s": run_s,
        "wall_per_sim_s": run_s / max(reached, 1e-12),
        "particle_steps_per_s": case.scene.capacity * steps / run_s,
        "saved": {k: v.tolist() for k, v in saved.items()},
        "history": {k: v.tolist() for k, v in history.items()},
    }
    if adaptive:
        names = [k for k in saved if k.startswith("limit_")]
        stack = np.stack([saved[k] for k in names])
        ok = np.asarray(saved["time"]) <= reached + 1e-12
        binding = [names[i][6:] for i in np.argmin(stack, axis=0)[ok]]
        record["binding"] = {n: binding.count(n) for n in sorted(set(binding))}
    return record


def dam_break_scaled(scale: float, spacing: float, **settings):
    geometry = {k: scale * v for k, v in LOBOVSKY.items()}
    geometry["tank_height"] = max(0.438, 0.438 * scale)
    return jaxmps.scenes.dam_break(spacing=spacing, **geometry, **settings)


_DEFAULTS = ("semi_implicit", "standard")


def runs_to_end(args) -> list[dict]:
    rows = []
    for scale in args.scales:
        settings = {} if args.courant is None else {"courant": args.courant}
        case = dam_break_scaled(
            scale, args.spacing, solver=args.solver, scheme=args.scheme, **settings
        )
        record = rollout(case, args.t_end, args.save_every)
        courant = case.scene.time_step.courant_for(case.scene)
        variant = [v for v in (args.solver, args.scheme) if v not in _DEFAULTS]
        mode = " ".join(["adaptive", *variant])
        record.update(geometry=f"{scale:g}x", mode=mode, courant=courant)
        rows.append(record)
        _say(record)
        dt = float(case.params.dt)
        if args.courant is not None or variant:
            continue  # the fixed-step scan is the default scheme's, at its Courant
        for halving in range(args.max_halvings + 1):
            fixed = dam_break_scaled(scale, args.spacing, dt=dt / 2**halving)
            record = rollout(fixed, args.t_end, args.save_every)
            record.update(geometry=f"{scale:g}x", mode=f"fixed dt/{2**halving}")
            rows.append(record)
            _say(record)
            if record["result"] == "successful" or scale not in args.scan_scales:
                break
    return rows


def _series(name: str, series: str):
    rows = [
        line.split(",")
        for line in (DATA / name).read_text().splitlines()
        if line and not line.startswith("#")
    ][1:]
    pts = [(float(r[-2]), float(r[-1])) for r in rows if r[0] == series]
    return np.array(pts).T


def accuracy(args) -> list[dict]:
    rows = []
    l0 = args.accuracy_spacing
    cases = {
        "dam_break": lambda **s: jaxmps.scenes.dam_break(spacing=0.00730, **s),
        "hydrostatic": lambda **s: jaxmps.scenes.hydrostatic(
            spacing=l0, width=0.2, depth=0.2, **s
        ),
        "standing_wave": lambda **s: jaxmps.scenes.standing_wave(
            spacing=l0, tank_length=0.4, depth=0.2, tank_height=0.3, amplitude=0.02, **s
        ),
    }
    ends = {"dam_break": 0.45, "hydrostatic": 1.0, "standing_wave": 1.6}
    saves = {"dam_break": 0.005, "hydrostatic": 0.01, "standing_wave": 0.005}
    for name, build in cases.items():
        adaptive = build()
        for mode, case in (
            ("adaptive", adaptive),
            ("fixed", build(dt=float(adaptive.params.dt))),
        ):
            record = rollout(case, ends[name], saves[name])
            record.update(case=name, mode=mode, **_error(name, case, record))
            rows.append(record)
            _say(record)
    return rows


def _error(name: str, case, record) -> dict:
    saved = {k: np.asarray(v) for k, v in record["saved"].items()}
    t = saved["time"]
    if name == "dam_break":
        a = float(case.config["column_width"])
        big_t = t * math.sqrt(2 * G / a)
        z = saved["front"] / a
        rt, rz = _series("martin_moyce_1952_surge_front.csv", "mm_a2.25_tab")
        rel = [
            float(np.interp(T, big_t, z) / np.interp(T, rt, rz) - 1) for T in T_CHECK
        ]
        return {
            "front_rel": rel,
            "error": max(abs(r) for r in rel),
            "measure": "max abs(Z/Z_MM - 1), T = 1-2.5",
        }
    if name == "hydrostatic":
        late = t >= 0.5
        p = saved["pressure_bottom"][late]
        return {
            "error": float(np.std(p) / np.mean(p)),
            "measure": "std/mean of bottom pressure, t >= 0.5 s",
        }
    mode = saved["mode"] - saved["mode"].mean()
    i = np.nonzero(np.sign(mode[:-1]) != np.sign(mode[1:]))[0]
    crossings = t[i] - mode[i] * (t[i + 1] - t[i]) / (mode[i + 1] - mode[i])
    period = 2 * float(np.mean(np.diff(crossings))) if len(i) > 2 else math.nan
    linear = float(case.config["linear_period"])
    return {
        "period": period,
        "error": abs(period / linear - 1),
        "measure": "abs(T / T_linear - 1)",
    }


def _say(record: dict) -> None:
    label = record.get("geometry") or record.get("case")
    print(
        f"{label:>13} {record['mode']:>13}: {record['result']:<22} "
        f"t={record['reached_s']:.3f} s, {record['steps']} steps "
        f"({record['rejected']} again), {record['wall_per_sim_s']:.1f} s/s, "
        f"compile {record['compile_s']:.1f} s"
        + (f", error {record['error']:.4f}" if "error" in record else ""),
        flush=True,
    )


def markdown(data: dict) -> str:
    lines = [
        "# Adaptive against fixed time steps",
        "",
        f"Machine: {data['machine'].get('cpu_model', '?')}, backend "
        f"{data['machine'].get('backend', '?')}; float"
        f"{'64' if data['x64'] else '32'}. Script: `benchmarks/adaptive_steps.py`"
        f"{' --quick' if data['quick'] else ''}.",
        "",
        f"## Dam break, 0.6 m x 0.3 m column in a 1.61 m tank (x scale), "
        f"l0 = {data['spacing']:g} m, to {data['t_end']:g} s at defaults",
        "",
        "| tank | stepping | dt [ms] | result | reached [s] | steps | taken again "
        "| wall / simulated s | compile [s] | limits setting dt (saves) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in data["runs"]:
        mode = r["mode"] + (f" C={r['courant']:g}" if r.get("courant") else "")
        lines.append(
            f"| {r['geometry']} | {mode} | {1e3 * r['dt']:.3f} | {r['result']} "
            f"| {r['reached_s']:.3f} | {r['steps']} | {r['rejected']} "
            f"| {r['wall_per_sim_s']:.1f} | {r['compile_s']:.1f} "
            f"| {', '.join(f'{k} {v}' for k, v in r.get('binding', {}).items())} |"
        )
    lines += [
        "",
        "dt [ms]: `Params.dt`, the largest step (adaptive) or the step (fixed).",
        "",
        "## Accuracy and cost at the same largest step",
        "",
        "| case | stepping | result | steps | wall / simulated s | error | measure |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in data["accuracy"]:
        lines.append(
            f"| {r['case']} | {r['mode']} | {r['result']} | {r['steps']} "
            f"| {r['wall_per_sim_s']:.1f} | {r['error']:.4f} | {r['measure']} |"
        )
    return "\n".join(lines) + "\n"


def plot(data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [r for r in data["runs"] if r["mode"] == "adaptive"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for r in runs:
        h = r["history"]
        t = np.asarray(r["saved"]["time"])
        label = f"{r['geometry']} C={r.get('courant', float('nan')):g}"
        axes[0].plot(t, 1e3 * np.asarray(h["dt_min"]), label=f"{label} min")
        axes[0].plot(
            t,
            1e3 * np.asarray(h["dt_max"]),
            ":",
            color=axes[0].lines[-1].get_color(),
            label=f"{label} max",
        )
    axes[0].set(
        xlabel="t [s]",
        ylabel="dt between saves [ms]",
        title="dt of the adaptive dam breaks",
    )
    axes[0].legend(fontsize=7)
    base = next((r for r in runs if r["geometry"] == "1x"), runs[0])
    names = [k for k in base["saved"] if k.startswith("limit_")]
    t = np.asarray(base["saved"]["time"])
    for k in names:
        v = np.asarray(base["saved"][k])
        if np.all(~np.isfinite(v)):
            continue
        axes[1].semilogy(t, 1e3 * v, label=k[6:])
    axes[1].set(
        xlabel="t [s]",
        ylabel="limit [ms]",
        title=f"limits at the saves ({base['geometry']} tank)",
    )
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _merged(old: list, new: list, keys: tuple) -> list:
    """`old` rows without those `new` replaces (equal `keys`), then `new`."""
    replaced = {tuple(r.get(k) for k in keys) for r in new}
    return [r for r in old if tuple(r.get(k) for k in keys) not in replaced] + new


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--x64", action="store_true")
    p.add_argument("--parts", nargs="+", default=["runs", "accuracy"])
    p.add_argument("--scales", type=float, nargs="+", default=None)
    p.add_argument(
        "--courant", type=float, default=None, help="the adaptive runs' Courant"
    )
    p.add_argument(
        "--solver",
        default="semi_implicit",
        help="the adaptive runs' solver (`explicit`: no fixed scan)",
    )
    p.add_argument(
        "--scheme",
        default="standard",
        help="the adaptive runs' scheme (standard_ds, high_accuracy; no fixed scan)",
    )
    p.add_argument("--merge", action="store_true", help="add to the results file")
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    if args.x64:
        jax.config.update("jax_enable_x64", True)
    args.spacing = 0.02 if args.quick else 0.01
    args.t_end = 1.0 if args.quick else 2.0
    args.save_every = 0.01
    args.scales = tuple(args.scales or ((1.0,) if args.quick else (1.0, 2.0, 0.5)))
    args.max_halvings = 3
    args.scan_scales = (1.0,)  # the fixed-dt scan only here (runs are long)
    args.accuracy_spacing = 0.02 if args.quick else 0.01
    backend = jax.default_backend()
    out = (
        Path(args.out)
        if args.out
        else ROOT
        / "results"
        / (f"adaptive_steps{'_quick' if args.quick else ''}_{backend}")
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    data = {"runs": [], "accuracy": []}
    if args.merge and out.with_suffix(".json").exists():
        data = json.loads(out.with_suffix(".json").read_text())
    data.update(
        machine=machine_info(),
        x64=bool(args.x64),
        quick=bool(args.quick),
        spacing=args.spacing,
        t_end=args.t_end,
    )
    if "runs" in args.parts:
        rows = runs_to_end(args)
        data["runs"] = _merged(data["runs"], rows, ("geometry", "mode", "courant"))
        _write(data, out)
    if "accuracy" in args.parts:
        rows = accuracy(args)
        data["accuracy"] = _merged(data["accuracy"], rows, ("case", "mode"))
        _write(data, out)
    print(f"wrote {out}.{{json,md,png}}")


def _write(data: dict, out: Path) -> None:
    out.with_suffix(".json").write_text(json.dumps(data, indent=1))
    out.with_suffix(".md").write_text(markdown(data))
    plot(data, out.with_suffix(".png"))


if __name__ == "__main__":
    main()
