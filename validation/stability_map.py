"""Stability map: where each solver stays stable and accurate as the knobs turn.

One knob at a time is moved away from a base setting, per method (`semi_implicit`
standard MPS, `high_accuracy` = semi-implicit MPS-HS-HL-ECS-GC-DS-WEND, `explicit`
E-MPS) and per precision (float64, float32; each in its own process):

| axis | values | case, reference |
|---|---|---|
| dt | 1e-3 .. 2 x the time-step limit | hydrostatic pressure; wave period (>= 0.1) |
| spacing | 0.02, 0.01, 0.005 m (4x) | hydrostatic pressure |
| viscosity | 0, 1e-6, 1e-4, 1e-3, 1e-2 m^2/s | hydrostatic pressure |
| rtol | 1e-2 .. 1e-10 (semi-implicit methods) | hydrostatic pressure |
| density ratio | 0.1 .. 10 (rigid box) | Archimedes draft (< 1) / rest on floor (> 1) |

Time-step limit of a method (the `dt` axis is in units of it):
* semi-implicit: the run-time Courant check, `Scene.courant_limit` (0.5) x l0 / U with
  the scene's velocity scale U (sqrt(2 g H) for the tank; sqrt(g H) for the wave);
* explicit: the sound-speed limit of seed 002 (eq. 3.40), c dt / l0 = 1; the solver
  itself refuses dt beyond `Explicit.sound_courant` (0.8) x l0 / c.
Runs past a limit are started with the start-up check switched off where one
exists (`Explicit(check_time_step=False)`, `viscous_limit=inf` is NOT set: the
viscous check stays), so the map shows what the run-time checks make of them.

Base: 0.2 m x 0.2 m hydrostatic tank, l0 = 0.01 m, the scene's default dt, run to
1 s (at most `--max-steps` steps; a tiny dt reaches less: its error is then that of
the time reached and marked so); error = |P_bottom / (rho g (H - l0/2 - y_p)) - 1|
averaged over the second half of the run (y_p: the probe's particles' mean initial
height, as in accuracy_vs_cost.py); noise = std of P_bottom over the same window /
reference. Standing wave: 0.4 m tank, 0.2 m deep, A = 2 cm, l0 = 0.01 m, 1.6 s;
error = |period / linear period - 1|. Floating box: 0.2 x 0.1 m box in a 0.8 m tank,
l0 = 0.02 m, 1.2 s; error = |mean draft over t > 0.4 s - ratio x height| / l0 for
ratio < 1, |box bottom face - floor| / l0 for ratio > 1 (the box sinks from just
submerged to rest on the floor).

Verdicts: `ok` (successful, error within the axis's bound), `inaccurate` (successful
but beyond it: hydrostatic 5 %, wave period 5 %, draft 1 l0), or the name of the
`Result` the run ended with (the clear error a user gets).

Cost: run time of one call of the compiled rollout (compile timed separately and
excluded), per simulated second.

Run (~60-70 min on 2 CPU cores for both precisions):

    python validation/stability_map.py                  # both precisions, all axes
    python validation/stability_map.py --precisions float64 --axes dt viscosity
    python validation/stability_map.py --replot         # redraw MD/PNG from JSON

Writes results/stability_map_<cpu|gpu>.{json,md,png}.
"""

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
METHODS = ("semi_implicit", "high_accuracy", "explicit")
AXES = ("dt", "spacing", "viscosity", "rtol", "density_ratio")
DT_FACTORS = (1e-3, 1e-2, 0.1, 0.5, 1.0, 1.5, 2.0)
SPACINGS = (0.02, 0.01, 0.005)
VISCOSITIES = (0.0, 1e-6, 1e-4, 1e-3, 1e-2)
RTOLS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
DENSITY_RATIOS = (0.1, 0.25, 0.5, 0.75, 0.9, 2.0, 10.0)
BOUND = {"hydrostatic": 0.05, "standing_wave": 0.05, "floating_box": 1.0}
T_HYDRO, T_WAVE, T_BOX = 1.0, 1.6, 1.2
WAVE = dict(tank_length=0.4, depth=0.2, tank_height=0.3, amplitude=0.02)
G = 9.81


# --------------------------------------------------------------------- one process


def _setup(precision: str):
    import jax

    jax.config.update("jax_enable_x64", precision == "float64")


def _method_settings(method: str) -> dict:
    return {
        "semi_implicit": dict(solver="semi_implicit"),
        "high_accuracy": dict(solver="semi_implicit", scheme="high_accuracy"),
        "explicit": dict(solver="explicit"),
    }[method]


def _dt_limit(case, method: str, velocity_scale: float) -> float:
    scene, params = case.scene, case.params
    if method == "explicit":
        # Seed 002 eq. 3.40's limit c dt / l0 = 1 (the solver refuses beyond
        # `Explicit.sound_courant`, 0.8 by default, where accuracy was measured).
        return scene.spacing / float(params.sound_speed)
    return scene.courant_limit * scene.spacing / velocity_scale


def _build(name: str, method: str, **settings):
    import equinox as eqx

    import jaxmps

    build = getattr(jaxmps.scenes, name)
    case = build(**_method_settings(method), **settings)
    if method == "explicit":
        # Let a dt past the sound-speed limit start; the run-time check stays.
        solver = eqx.tree_at(lambda s: s.check_time_step, case.scene.solver, False)
        case = eqx.tree_at(lambda c: c.scene.solver, case, solver)
    return case


def _rollout(case, t_end: float, max_steps: int, saves: int, extra_observe=None):
    """Compile, then time one call of the compiled rollout. Returns (traj, timing)."""
    from _common import compile_timed, time_calls

    import jaxmps

    dt = float(case.params.dt)
    n = max(1, min(max_steps, int(math.ceil(t_end / dt))))
    save_every = max(1, n // saves)
    n = math.ceil(n / save_every) * save_every
    observe = jaxmps.scenes.observe_probes(case.probes)
    if extra_observe is not None:
        observe = extra_observe(observe)
    args = (case.scene, case.params, case.state, n, save_every, observe)
    kwargs = dict(throw=False, checkpoint=True)
    try:
        # lower_simulate runs simulate's checks
        compiled, lower_s, compile_s = compile_timed(
            jaxmps.lower_simulate, *args, **kwargs
        )
    except ValueError as error:  # refused before running: that is the verdict
        return None, {"refused": str(error).split("\n")[0], "n_steps": n}
    timing = {"compile_s": lower_s + compile_s}
    # One call only (the run is the verdict): its time is the warm-up's.
    traj, timing["run_s"], _ = time_calls(lambda: compiled(*args, **kwargs), repeats=0)
    timing.update(n_steps=n, save_every=save_every, dt=dt)
    return traj, timing


def _hydrostatic_error(case, saved, l0: float) -> dict:
    t = saved["time"]
    late = t >= 0.5 * t[-1] - 1e-12
    import jaxmps

    reference = jaxmps.scenes.hydrostatic_pressure(case)
    p = saved["pressure_bottom"][late]
    level = saved["water_level"]
    return {
        "error": abs(float(np.mean(p)) / reference - 1),
        "noise": float(np.std(p)) / reference,
        "level_drift_l0": float(level[-1] - level[0]) / l0,
    }


def _wave_error(case, saved) -> dict:
    t, mode = saved["time"], saved["mode"]
    m = mode - mode.mean()
    i = np.nonzero(np.sign(m[:-1]) != np.sign(m[1:]))[0]
    if len(i) < 3:
        return {"error": math.nan, "period": math.nan}
    crossings = t[i] - m[i] * (t[i + 1] - t[i]) / (m[i + 1] - m[i])
    period = 2 * float(np.mean(np.diff(crossings)))
    linear = float(case.config["linear_period"])
    return {"error": abs(period / linear - 1), "period": period, "linear": linear}


def _box_error(case, saved, ratio: float) -> dict:
    c = case.config
    l0, height = c["spacing"], c["box_height"]
    late = saved["time"] > 0.4
    bottom = saved["box_y"][late] - 0.5 * height
    if ratio < 1:
        surface = 0.5 * (saved["level_left"] + saved["level_right"])[late] - 0.5 * l0
        draft = float(np.mean(surface - bottom))
        return {"error": abs(draft - ratio * height) / l0, "draft_l0": draft / l0}
    # Resting on the floor: the floor's wall particles sit at y = -l0/2, so a box
    # whose lowest particles lie one spacing above them has its face at y = 0.
    gap = float(np.mean(bottom)) / l0
    return {"error": abs(gap), "gap_l0": gap}


def run_one(method: str, axis: str, value: float, max_steps: int) -> list[dict]:
    import jax.numpy as jnp
    from _common import result_name

    rows = []
    cases = []
    if axis == "density_ratio":
        # A sinking box (ratio > 1) starts just submerged.
        draft = None if value < 1 else 0.1
        case = _build(
            "floating_box",
            method,
            spacing=0.02,
            density_ratio=value,
            initial_draft=draft,
        )
        cases.append(("floating_box", case, T_BOX))
    else:
        settings = {"spacing": 0.01}
        if axis == "spacing":
            settings["spacing"] = value
        elif axis == "viscosity":
            settings["viscosity"] = value
        elif axis == "rtol":
            settings["rtol"] = value
        hydro = dict(width=0.2, depth=0.2, **settings)
        case = _build("hydrostatic", method, **hydro)
        if axis == "dt":
            limit = _dt_limit(case, method, math.sqrt(2 * G * 0.2))
            case = _build("hydrostatic", method, dt=value * limit, **hydro)
        cases.append(("hydrostatic", case, T_HYDRO))
        if axis == "dt" and value >= 0.1:  # below, no period within max_steps
            wave = _build("standing_wave", method, spacing=0.01, **WAVE)
            limit = _dt_limit(wave, method, math.sqrt(9.8 * 0.2))
            wave = _build(
                "standing_wave", method, spacing=0.01, dt=value * limit, **WAVE
            )
            cases.append(("standing_wave", wave, T_WAVE))
    for name, case, t_end in cases:
        row = {
            "method": method,
            "axis": axis,
            "value": value,
            "case": name,
            "dtype": str(jnp.zeros(()).dtype),
            "capacity": int(case.scene.capacity),
            "dt": float(case.params.dt),
        }
        traj, timing = _rollout(case, t_end, max_steps, saves=100)
        row.update(timing)
        if traj is None:
            row.update(verdict="refused", result="refused at start")
            rows.append(row)
            continue
        saved = {k: np.asarray(v, float) for k, v in traj.saved.items()}
        row["result"] = result_name(traj.result)
        row["t_reached"] = float(traj.state.time)
        row["t_end"] = t_end
        row["complete"] = row["t_reached"] >= 0.98 * t_end
        row["wall_per_sim_s"] = timing["run_s"] / max(row["t_reached"], 1e-12)
        row["particle_steps_per_s"] = (
            case.scene.capacity * row["n_steps"] / max(timing["run_s"], 1e-12)
        )
        if row["result"] != "successful":
            row["verdict"] = row["result"]
        else:
            # Only the frames before any failure are meaningful; all are here.
            if name == "hydrostatic":
                row.update(_hydrostatic_error(case, saved, case.scene.spacing))
            elif name == "standing_wave":
                row.update(_wave_error(case, saved))
            else:
                row.update(_box_error(case, saved, value))
            err = row.get("error", math.nan)
            good = np.isfinite(err) and err <= BOUND[name]
            row["verdict"] = "ok" if good else "inaccurate"
            if not row["complete"]:
                row["verdict"] += " (partial)"
        rows.append(row)
        print(
            f"{row['dtype']} {method:14s} {axis:13s} {value:<8.3g} {name:14s} "
            f"{row['verdict']:24s} err={row.get('error', math.nan):.3g} "
            f"wall/sim={row.get('wall_per_sim_s', math.nan):.3g}",
            flush=True,
        )
    return rows


def values_of(axis: str):
    return {
        "dt": DT_FACTORS,
        "spacing": SPACINGS,
        "viscosity": VISCOSITIES,
        "rtol": RTOLS,
        "density_ratio": DENSITY_RATIOS,
    }[axis]


def worker(args) -> None:
    _setup(args.precision)
    rows = []
    for method in args.methods:
        for axis in args.axes:
            if axis == "rtol" and method == "explicit":
                continue
            values = values_of(axis)
            if axis == "dt" and args.dt_factors:
                values = tuple(args.dt_factors)
            for value in values:
                rows.extend(run_one(method, axis, value, args.max_steps))
                Path(args.part).write_text(json.dumps(rows, indent=1))


# --------------------------------------------------------------------- the driver


def _verdict(row) -> str:
    """The row's verdict, "(partial)" when the run stopped short of its end time at
    `--max-steps` (derived here, so that rows of any version read alike)."""
    base = row["verdict"].replace(" (partial)", "")
    t_end = {"hydrostatic": T_HYDRO, "standing_wave": T_WAVE}.get(row["case"], T_BOX)
    if base in ("ok", "inaccurate") and row.get("t_reached", 0) < 0.98 * t_end:
        return f"{base} (partial: t = {row['t_reached']:.2g} s)"
    return base


def _fmt_value(axis, v):
    if axis == "dt":
        return f"{v:g} x limit"
    return f"{v:g}"


def markdown(data: dict) -> str:
    rows = data["rows"]
    m = data["machine"]
    out = [
        "# Stability map (CPU, 2 cores)"
        if m["backend"] == "cpu"
        else "# Stability map",
        "",
        f"- machine: {m['platform']}, {m['cpu_model']}, {m['cpu_usable']} usable cores",
        f"- jax {m['jax']}, jaxmps {m['jaxmps']}, git {m['git_commit']}",
        f"- at most {data['max_steps']} steps per run; verdict bounds: hydrostatic "
        "pressure 5 %, wave period 5 %, draft 1 l0",
        "- error: hydrostatic |P/P_ref - 1|, standing wave |T/T_lin - 1|, floating "
        "box draft (or floor gap) error in l0; wall/sim.s: run time per simulated "
        "second, compile excluded",
        "",
    ]
    for dtype in ("float64", "float32"):
        sub = [r for r in rows if r["dtype"] == dtype]
        if not sub:
            continue
        out += [
            f"## {dtype}",
            "",
            "| method | axis | value | case | dt [s] | verdict | error | noise | "
            "wall/sim.s [s] |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in sub:
            err = r.get("error")
            noise = r.get("noise")
            out.append(
                f"| {r['method']} | {r['axis']} | {_fmt_value(r['axis'], r['value'])} "
                f"| {r['case']} | {r['dt']:.3g} | {_verdict(r)} | "
                + (f"{err:.3g}" if err is not None else "-")
                + " | "
                + (f"{noise:.3g}" if noise is not None else "-")
                + " | "
                + (
                    f"{r['wall_per_sim_s']:.3g}"
                    if r.get("wall_per_sim_s") is not None
                    else "-"
                )
                + " |"
            )
        out.append("")
    return "\n".join(out)


def plot(data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = data["rows"]
    axes = [a for a in AXES if any(r["axis"] == a for r in rows)]
    fig, panels = plt.subplots(
        1, len(axes), figsize=(3.6 * len(axes), 3.6), squeeze=False
    )
    colour = {"semi_implicit": "C0", "high_accuracy": "C2", "explicit": "C3"}
    style = {"float64": "-", "float32": ":"}
    for ax, axis in zip(panels[0], axes):
        for method in METHODS:
            for dtype in ("float64", "float32"):
                sel = [
                    r
                    for r in rows
                    if r["axis"] == axis
                    and r["method"] == method
                    and r["dtype"] == dtype
                    and r["case"] != "standing_wave"
                ]
                if not sel:
                    continue
                x = [r["value"] if r["value"] > 0 else 1e-7 for r in sel]
                y = [
                    r.get("error", math.nan)
                    if r["verdict"].startswith(("ok", "in"))
                    else math.nan
                    for r in sel
                ]
                ax.plot(
                    x,
                    y,
                    style[dtype],
                    marker="o",
                    color=colour[method],
                    label=f"{method} {dtype}",
                )
                for xi, r in zip(x, sel):
                    if not r["verdict"].startswith(("ok", "inaccurate")):
                        ax.plot(xi, 1.0, "x", color=colour[method], ms=9)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(
            {"dt": "dt / limit", "density_ratio": "body / water density"}.get(
                axis, axis
            )
        )
        title = {
            "density_ratio": "density ratio (draft err. / l0)",
            "viscosity": "viscosity (0 plotted at 1e-7)",
        }
        ax.set_title(title.get(axis, axis))
        ax.grid(True, which="both", alpha=0.3)
    panels[0][0].set_ylabel("error (x at top: run ended with an error)")
    panels[0][0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--axes", nargs="+", default=list(AXES), choices=AXES)
    parser.add_argument(
        "--precisions",
        nargs="+",
        default=["float64", "float32"],
        choices=["float64", "float32"],
    )
    parser.add_argument("--max-steps", type=int, default=2000)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--replot", action="store_true")
    parser.add_argument(
        "--merge",
        action="store_true",
        help="replace the rows of the given precisions/methods/axes in the JSON",
    )
    parser.add_argument(
        "--dt-factors",
        nargs="+",
        type=float,
        default=None,
        help=f"dt axis values in units of the limit (default {DT_FACTORS})",
    )
    # Internal: one precision in this process.
    parser.add_argument("--precision", help=argparse.SUPPRESS)
    parser.add_argument("--part", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.precision:
        worker(args)
        return
    import jax

    sys.path.insert(0, str(HERE))
    from _common import loadavg, machine_info

    out = args.out or HERE / "results" / f"stability_map_{jax.default_backend()}"
    out.parent.mkdir(parents=True, exist_ok=True)
    if not args.replot:
        rows = []
        for precision in args.precisions:
            part = out.with_suffix(f".{precision}.part.json")
            cmd = [
                sys.executable,
                __file__,
                "--precision",
                precision,
                "--part",
                str(part),
                "--max-steps",
                str(args.max_steps),
                "--methods",
                *args.methods,
                "--axes",
                *args.axes,
            ]
            if args.dt_factors:
                cmd += ["--dt-factors", *map(str, args.dt_factors)]
            subprocess.run(cmd, check=True)
            rows.extend(json.loads(part.read_text()))
            part.unlink()
        info = machine_info()
        info["loadavg_1min_end"] = loadavg()
        if args.merge and out.with_suffix(".json").exists():
            old = json.loads(out.with_suffix(".json").read_text())
            replaced = {(r["dtype"], r["method"], r["axis"]) for r in rows}
            keep = [
                r
                for r in old["rows"]
                if (r["dtype"], r["method"], r["axis"]) not in replaced
            ]
            rows = keep + rows
            info["merged_into"] = old["machine"]
        data = {"machine": info, "max_steps": args.max_steps, "rows": rows}
        out.with_suffix(".json").write_text(json.dumps(data, indent=1))
    data = json.loads(out.with_suffix(".json").read_text())
    out.with_suffix(".md").write_text(markdown(data))
    plot(data, out.with_suffix(".png"))
    print(markdown(data))


if __name__ == "__main__":
    main()
