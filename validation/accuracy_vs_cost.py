"""Accuracy vs cost of the semi-implicit and explicit MPS solvers of `jaxmps`.

For each solver ("semi_implicit", "explicit") and three resolutions of two test cases:

* 2-D dam break (`jaxmps.scenes.dam_break`, spacing 0.0146 / 0.0073 / 0.00365 m, i.e.
  10 / 20 / 40 particles across the 0.146 m column), run to T = t sqrt(2g/a) = 2.6.
  Error = max over T in {1, 1.5, 2, 2.5} of |Z/Z_ref - 1| for the surge front
  Z = front/a, against Martin & Moyce 1952 (table series `mm_a2.25_tab`) and against
  SOLA-VOF (Hirt & Nichols 1981, series `openmps_vof_hirt_nichols1981`), both from
  `tests/data/*.csv` (interpolated linearly in T, as in `tests/test_validation.py`).
* Standing wave (`jaxmps.scenes.standing_wave`, 0.4 m pool, 0.2 m deep, A = 2 cm,
  spacing 0.02 / 0.01 / 0.005 m), run to 1.6 s (about three periods). Error =
  |T / T_linear - 1| for the period T of the cos(2 pi x / L) surface mode (probe
  `mode`, twice the mean spacing of its zero crossings); also reported: the mode's
  amplitude after the run relative to A (numerical damping).
* Hydrostatic tank (`jaxmps.scenes.hydrostatic`, 0.2 m x 0.2 m, spacing 0.02 / 0.01 /
  0.005 m), run to t = 1 s. `pressure_bottom` (mean pressure of the fluid within
  1.5 l0 of (width/2, l0/2)) is time-averaged over the saves with t >= 0.5 s, and
  compared with rho g (H - y_p), the weight of the water above the probe (see
  `scenes.hydrostatic_pressure`; the explicit solver, which holds P = 0 at the
  surface particles' centres, reads up to about l0/2 of head below it):
  - "nominal": y_p = l0/2 (the probe's centre), as in the tests;
  - "probe y" (the one plotted): y_p = the mean *initial* height of the particles the
    probe averages over (the first and second particle rows fall inside the 1.5 l0
    disc, so y_p > l0/2; e.g. 0.0167 m at l0 = 0.02);
  - "probe y(t)" (JSON only): y_p = the time-averaged mean height of the probed set
    over the same saves (an extra observation of this script).

Cost: the rollout (`jaxmps.simulate` to the end time by `times`, `throw=False`,
probes saved at fixed times) is timed by `_common.time_compiled`: compiled with
`jaxmps.lower_simulate(...).compile()` (compile time reported separately), then
called once untimed (warm-up; its output gives the errors) and timed over the best
of `--repeats` calls (one only when the warm-up took longer than `--max-timed-s`),
each ended by
`jax.block_until_ready`. Reported: wall time per simulated second
(run / simulated time), ms/step, particle-steps/s (capacity incl. walls/dummies x steps
/ run), and the default time step `case.params.dt` of each solver.

Usage:
    python validation/accuracy_vs_cost.py               # everything (~10 min, 2 CPU)
    python validation/accuracy_vs_cost.py --levels 0 1         # skip the finest level
    python validation/accuracy_vs_cost.py --cases dam_break --solvers explicit

Writes `validation/results/accuracy_vs_cost_<cpu|gpu>.{json,md,png}` (override with
`--out`, a path without extension). `--replot` redraws the MD/PNG from the JSON.
"""

import argparse
import json
import math
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import loadavg as _loadavg
from _common import machine_info, result_name, time_compiled

import jaxmps

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "tests" / "data"
SOLVERS = ("semi_implicit", "explicit", "high_accuracy")
# Method -> scene settings ("high_accuracy": the semi-implicit MPS-HS-HL-ECS-GC-DS-WEND
# scheme of seed 001).
METHOD = {
    "semi_implicit": dict(solver="semi_implicit"),
    "explicit": dict(solver="explicit"),
    "high_accuracy": dict(solver="semi_implicit", scheme="high_accuracy"),
}
SPACINGS = {
    "dam_break": (0.0146, 0.0073, 0.00365),
    "hydrostatic": (0.02, 0.01, 0.005),
    "standing_wave": (0.02, 0.01, 0.005),
}
# Standing wave (seed 001 §3.2 scaled down): 0.4 m pool, 0.2 m deep, A = 2 cm.
WAVE = dict(tank_length=0.4, depth=0.2, tank_height=0.3, amplitude=0.02)
T_END_WAVE = 1.6  # [s], about three periods
T_CHECK = (1.0, 1.5, 2.0, 2.5)
T_END_DAM = 2.6  # nondimensional end time of the dam break
T_END_HYDRO = 1.0  # [s]
RHO, G = 1000.0, 9.81


# ----------------------------------------------------------------------------- helpers


def _series(name: str, series: str):
    """(T, Z) of one series of a tests/data CSV (last two columns)."""
    rows = [
        line.split(",")
        for line in (DATA / name).read_text().splitlines()
        if line and not line.startswith("#")
    ][1:]
    pts = [(float(r[-2]), float(r[-1])) for r in rows if r[0] == series]
    return np.array(pts).T


REFERENCES = {
    "martin_moyce": ("martin_moyce_1952_surge_front.csv", "mm_a2.25_tab"),
    "sola_vof": ("koshizuka_oka_1996_surge_front.csv", "openmps_vof_hirt_nichols1981"),
}


class _Observer(eqx.Module):
    """The case's probes, plus (hydrostatic) the mean height of the bottom probe's
    particle set."""

    probes: tuple
    bottom: object  # FluidPressureNear or None

    def __call__(self, scene, state):
        out = {"time": state.time}
        for probe in self.probes:
            out[probe.name] = probe(scene, state)
        if self.bottom is not None:
            fluid = jnp.logical_and(state.active, state.kind == int(jaxmps.Kind.FLUID))
            point = jnp.asarray(self.bottom.point, dtype=state.position.dtype)
            d = state.position - point[None, :]
            near = fluid & (jnp.sum(d * d, axis=-1) < self.bottom.radius**2)
            y = jnp.sum(jnp.where(near, state.position[:, -1], 0.0))
            out["bottom_probe_y"] = y / jnp.maximum(jnp.sum(near), 1)
        return out


def _timed_rollout(scene, params, state, times, observe, args):
    """Compile, warm up, time (`_common.time_compiled`) the rollout to each of
    `times`. Returns (trajectory, timing dict)."""
    timed = time_compiled(
        jaxmps.lower_simulate,
        scene,
        params,
        state,
        times=times,
        observe=observe,
        throw=False,
        repeats=args.repeats,
        max_timed_s=args.max_timed_s,
    )
    return timed.output, {**timed.timing(), "compile_method": "lower"}


def _dam_break_errors(saved, a):
    t = np.asarray(saved["time"]) * math.sqrt(2 * G / a)
    z = np.asarray(saved["front"]) / a
    out = {}
    for key, (fname, series) in REFERENCES.items():
        rt, rz = _series(fname, series)
        rel = [float(np.interp(T, t, z) / np.interp(T, rt, rz) - 1) for T in T_CHECK]
        out[f"rel_{key}"] = rel
        out[f"err_{key}"] = max(abs(r) for r in rel)
    out["Z_at_T"] = [float(np.interp(T, t, z)) for T in T_CHECK]
    return out


def run_case(case_name: str, solver: str, spacing: float, args) -> dict:
    if case_name == "dam_break":
        case = jaxmps.scenes.dam_break(spacing=spacing, **METHOD[solver])
    elif case_name == "standing_wave":
        case = jaxmps.scenes.standing_wave(spacing=spacing, **WAVE, **METHOD[solver])
    else:
        case = jaxmps.scenes.hydrostatic(
            spacing=spacing, width=0.2, depth=0.2, **METHOD[solver]
        )
    scene, params, state = case.scene, case.params, case.state
    dt = float(params.dt)
    n_fluid = int(jnp.sum(state.active & (state.kind == int(jaxmps.Kind.FLUID))))
    record = {
        "case": case_name,
        "solver": solver,
        "spacing": spacing,
        "capacity": int(scene.capacity),
        "n_fluid": n_fluid,
        "dt": dt,
    }
    bottom = None
    if case_name == "dam_break":
        a = float(case.config["column_width"])
        t_end = T_END_DAM / math.sqrt(2 * G / a)
        save_dt = 0.025 / math.sqrt(2 * G / a)  # a save every ~0.025 in T
    elif case_name == "standing_wave":
        t_end, save_dt = T_END_WAVE, 0.005
    else:
        t_end = T_END_HYDRO
        save_dt = 0.01  # 100 saves per second
        bottom = next(p for p in case.probes if p.name == "pressure_bottom")
    # Choice: run to t_end by time, not by a step count: an adaptive scene's steps
    # may fall below Params.dt, and a fixed count of them then stops short of the
    # checks (the high-accuracy dam break reached T = 2.0 of 2.6, and its front
    # was read as standing still from there).
    saves = int(math.ceil(t_end / save_dt))
    times = np.linspace(t_end / saves, t_end, saves)
    observe = _Observer(probes=tuple(case.probes), bottom=bottom)

    traj, timing = _timed_rollout(scene, params, state, times, observe, args)
    simulated = float(traj.state.time)
    n_steps = int(np.asarray(traj.steps.accepted).sum())
    record.update(
        n_steps=n_steps,
        saves=saves,
        simulated_time_s=simulated,
        **timing,
    )
    run = timing["run_s_best"]
    record["wall_per_sim_s"] = run / simulated
    record["ms_per_step"] = 1e3 * run / n_steps
    record["particle_steps_per_s"] = scene.capacity * n_steps / run
    record["result"] = result_name(traj.result)
    record["successful"] = bool(traj.result == jaxmps.Result.successful)
    saved = {k: np.asarray(v) for k, v in traj.saved.items()}

    if case_name == "dam_break":
        record["column_width"] = a
        record.update(_dam_break_errors(saved, a))
        record["error"] = record["err_martin_moyce"]
    elif case_name == "standing_wave":
        t, mode = saved["time"], saved["mode"]
        m = mode - mode.mean()
        i = np.nonzero(np.sign(m[:-1]) != np.sign(m[1:]))[0]
        crossings = t[i] - m[i] * (t[i + 1] - t[i]) / (m[i + 1] - m[i])
        period = 2 * float(np.mean(np.diff(crossings))) if len(i) > 2 else math.nan
        linear = float(case.config["linear_period"])
        late = t > t[-1] - linear
        record.update(
            period=period,
            linear_period=linear,
            crossings=int(len(i)),
            rel_period=period / linear - 1,
            final_amplitude=float(np.abs(mode[late]).max() / WAVE["amplitude"]),
        )
        record["error"] = abs(record["rel_period"])
    else:
        l0, depth = spacing, float(case.config["depth"])
        late = saved["time"] >= 0.5 * T_END_HYDRO - 1e-9
        p_avg = float(np.nanmean(saved["pressure_bottom"][late]))
        pos = np.asarray(state.position)
        fluid = np.asarray(state.active) & (np.asarray(state.kind) == 0)
        d2 = ((pos - np.asarray(bottom.point)[None, :]) ** 2).sum(-1)
        near = fluid & (d2 < bottom.radius**2)
        y0 = float(pos[near, -1].mean())
        y_t = float(np.mean(saved["bottom_probe_y"][late]))
        surface = depth  # the weight of the water above y_p
        refs = {"nominal": 0.5 * l0, "probe_y0": y0, "probe_y_t": y_t}
        for key, y in refs.items():
            record[f"p_ref_{key}"] = RHO * G * (surface - y)
            record[f"err_{key}"] = abs(p_avg / (RHO * G * (surface - y)) - 1)
        record.update(
            depth=depth,
            p_bottom_avg=p_avg,
            probe_n_particles_initial=int(near.sum()),
            probe_y0=y0,
            probe_y_t=y_t,
            p_middle_avg=float(np.nanmean(saved["pressure_middle"][late])),
            max_speed_final=float(jnp.abs(traj.state.velocity).max()),
        )
        record["error"] = record["err_probe_y0"]
        # Pressure noise: standard deviation over time of the bottom probe, relative
        # to its reference (the noise measure).
        record["noise"] = float(
            np.nanstd(saved["pressure_bottom"][late]) / record["p_ref_probe_y0"]
        )
    record["loadavg_1min_end"] = _loadavg()
    return record


# ----------------------------------------------------------------------------- output


def _f(x, fmt=".2f"):
    return "?" if x is None else format(x, fmt)


def markdown(data: dict) -> str:
    info, rows = data["machine"], data["rows"]
    tag = "GPU" if info["backend"] == "gpu" else f"CPU ({info['cpu_usable']} cores)"
    lines = [
        f"# Accuracy vs cost: semi-implicit (standard, high-accuracy) vs explicit "
        f"MPS, {tag}",
        "",
        f"- machine: {info['platform']}, {info['cpu_model']}, "
        f"{info['cpu_usable']} usable / {info['cpu_count']} CPUs",
        f"- jax {info['jax']} (jaxlib {info['jaxlib']}), equinox {info['equinox']}, "
        f"jaxmps {info['jaxmps']}, python {info['python']}; dtype {info['dtype']}; "
        f"git {info['git_commit']}"
        + (" (uncommitted changes)" if info["git_dirty_tracked"] else ""),
        f"- 1-min load average: {_f(info.get('loadavg_1min_start'))} at start, "
        f"{_f(data.get('loadavg_1min_end'))} at end (> core count: other processes "
        "competed for the CPU, timings pessimistic)",
    ]
    dates = sorted({r.get("run_started") for r in rows if r.get("run_started")})
    if len(dates) > 1:
        lines.append(
            "- merged from runs started at " + ", ".join(dates) + " (`--merge`); "
            "per row: `run_started` and `loadavg_1min_end` in the JSON; machine line "
            "and start load average are those of the latest run"
        )
    lines += [
        "- run = best of up to "
        f"{data['settings']['repeats']} calls of the compiled rollout after one "
        "untimed warm-up call (one timed call only when the warm-up took longer than "
        f"{data['settings']['max_timed_s']:g} s); compile time (trace+lower / XLA) is "
        "separate and not in any other column. Default `case.params.dt` of each "
        "solver.",
        "",
    ]
    db = [r for r in rows if r["case"] == "dam_break"]
    if db:
        lines += [
            "## Dam break (to T = 2.6; error = max over T = 1, 1.5, 2, 2.5 of "
            "|Z/Z_ref - 1|)",
            "",
            "| solver | spacing [m] | particles (fluid) | dt [ms] | steps "
            "| err vs Martin & Moyce | err vs SOLA-VOF | wall / sim. s [s] "
            "| ms/step | particle-steps/s | compile [s] | result |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in db:
            lines.append(
                f"| {r['solver']} | {r['spacing']:g} "
                f"| {r['capacity']} ({r['n_fluid']}) "
                f"| {1e3 * r['dt']:.3f} | {r['n_steps']} "
                f"| {100 * r['err_martin_moyce']:.1f} % "
                f"| {100 * r['err_sola_vof']:.1f} % "
                f"| {r['wall_per_sim_s']:.3g} | {r['ms_per_step']:.2f} "
                f"| {r['particle_steps_per_s']:.3g} "
                f"| {r['trace_lower_s'] + r['compile_s']:.1f} "
                f"| {'ok' if r['successful'] else r['result']} |"
            )
        lines += [
            "",
            "Signed Z/Z_ref - 1 at T = 1 / 1.5 / 2 / 2.5 (Martin & Moyce; SOLA-VOF):",
            "",
        ]
        for r in db:
            mm = " / ".join(f"{100 * x:+.0f}" for x in r["rel_martin_moyce"])
            vof = " / ".join(f"{100 * x:+.0f}" for x in r["rel_sola_vof"])
            lines.append(f"- {r['solver']}, {r['spacing']:g} m: {mm} %; {vof} %")
        lines.append("")
    sw = [r for r in rows if r["case"] == "standing_wave"]
    if sw:
        lines += [
            "## Standing wave 0.4 m x 0.2 m, A = 2 cm (to 1.6 s; period of the "
            "cos(2 pi x / L) mode from its zero crossings)",
            "",
            "| method | spacing [m] | particles (fluid) | dt [ms] | steps "
            "| period error | amplitude at the end / A | wall / sim. s [s] "
            "| ms/step | particle-steps/s | compile [s] | result |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in sw:
            lines.append(
                f"| {r['solver']} | {r['spacing']:g} "
                f"| {r['capacity']} ({r['n_fluid']}) "
                f"| {1e3 * r['dt']:.3f} | {r['n_steps']} "
                f"| {100 * r['rel_period']:+.2f} % | {r['final_amplitude']:.2f} "
                f"| {r['wall_per_sim_s']:.3g} | {r['ms_per_step']:.2f} "
                f"| {r['particle_steps_per_s']:.3g} "
                f"| {r['trace_lower_s'] + r['compile_s']:.1f} "
                f"| {'ok' if r['successful'] else r['result']} |"
            )
        lines.append("")
    hs = [r for r in rows if r["case"] == "hydrostatic"]
    if hs:
        lines += [
            "## Hydrostatic tank 0.2 m x 0.2 m (to t = 1 s; `pressure_bottom` "
            "averaged over t >= 0.5 s)",
            "",
            "Reference rho g (H - y_p). **err (probe y)**: y_p = mean initial "
            "height of the probed particles (plotted); **err (nominal)**: y_p = l0/2.",
            "",
            "| solver | spacing [m] | particles (fluid) | dt [ms] | steps "
            "| P_bottom avg [Pa] | y_p [mm] | err (probe y) | err (nominal) "
            "| noise (std) | wall / sim. s [s] | ms/step | particle-steps/s "
            "| compile [s] | result |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in hs:
            lines.append(
                f"| {r['solver']} | {r['spacing']:g} "
                f"| {r['capacity']} ({r['n_fluid']}) "
                f"| {1e3 * r['dt']:.3f} | {r['n_steps']} | {r['p_bottom_avg']:.0f} "
                f"| {1e3 * r['probe_y0']:.1f} "
                f"| {100 * r['err_probe_y0']:.2f} % | {100 * r['err_nominal']:.2f} % "
                f"| {_pct(r.get('noise'))} "
                f"| {r['wall_per_sim_s']:.3g} | {r['ms_per_step']:.2f} "
                f"| {r['particle_steps_per_s']:.3g} "
                f"| {r['trace_lower_s'] + r['compile_s']:.1f} "
                f"| {'ok' if r['successful'] else r['result']} |"
            )
        lines.append("")
    if data.get("skipped"):
        lines += ["Skipped: " + "; ".join(data["skipped"]), ""]
    return "\n".join(lines) + "\n"


def _pct(x):
    return "?" if x is None else f"{100 * x:.2f} %"


def _tick(v, _pos=None):
    return f"{v:g}"


def _minor_tick(v, _pos=None):
    """Label the 2 and 5 minor ticks of a log axis."""
    if v <= 0:
        return ""
    mantissa = v / 10 ** math.floor(math.log10(v) + 1e-9)
    return f"{v:g}" if round(mantissa, 6) in (2.0, 5.0) else ""


def plot(data: dict, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    rows = data["rows"]
    cases = [
        c
        for c in ("dam_break", "hydrostatic", "standing_wave")
        if any(r["case"] == c for r in rows)
    ]
    fig, axes = plt.subplots(
        1, len(cases), figsize=(5.5 * len(cases), 5.0), squeeze=False
    )
    markers = ("o", "s", "^", "D")
    colours = {"semi_implicit": "C0", "explicit": "C3", "high_accuracy": "C2"}
    labels = {
        "dam_break": "dam break: max |Z/Z_ref - 1| at T = 1, 1.5, 2, 2.5\n"
        "filled: vs Martin & Moyce 1952; open: vs SOLA-VOF",
        "hydrostatic": "hydrostatic 0.2 m tank: "
        "|P_bottom / rho g (H - y_p) - 1|\n"
        "P_bottom averaged over 0.5-1 s; y_p = mean initial probe height",
        "standing_wave": "standing wave 0.4 m x 0.2 m, A = 2 cm:\n"
        "|T / T_linear - 1| of the surface mode over 1.6 s",
    }
    for ax, case in zip(axes[0], cases):
        for solver in SOLVERS:
            rs = sorted(
                (r for r in rows if r["case"] == case and r["solver"] == solver),
                key=lambda r: -r["spacing"],
            )
            if not rs:
                continue
            x = [r["wall_per_sim_s"] for r in rs]
            y = [max(r["error"], 1e-4) for r in rs]
            ax.plot(x, y, "-", color=colours[solver], label=solver)
            for i, r in enumerate(rs):
                ax.plot(
                    x[i],
                    y[i],
                    markers[SPACINGS[case].index(r["spacing"])]
                    if r["spacing"] in SPACINGS[case]
                    else "x",
                    color=colours[solver],
                    ms=8,
                )
                ax.annotate(
                    f"{r['spacing']:g}",
                    (x[i], y[i]),
                    textcoords="offset points",
                    xytext=(5, 4),
                    fontsize=8,
                )
            if case == "dam_break":
                yv = [max(r["err_sola_vof"], 1e-4) for r in rs]
                ax.plot(
                    x,
                    yv,
                    ":",
                    color=colours[solver],
                    alpha=0.7,
                    label=f"{solver} (vs SOLA-VOF, open markers)",
                )
                for i, r in enumerate(rs):
                    ax.plot(
                        x[i],
                        yv[i],
                        markers[SPACINGS[case].index(r["spacing"])]
                        if r["spacing"] in SPACINGS[case]
                        else "x",
                        mfc="none",
                        color=colours[solver],
                        ms=8,
                        alpha=0.7,
                    )
        ax.set_xscale("log")
        ax.set_yscale("log")
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(matplotlib.ticker.FuncFormatter(_tick))
            axis.set_minor_formatter(matplotlib.ticker.FuncFormatter(_minor_tick))
        ax.set_xlabel("wall time per simulated second [s]")
        ax.set_ylabel("relative error")
        ax.set_title(labels[case], fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)
    info = data["machine"]
    fig.suptitle(
        f"jaxmps accuracy vs cost ({info['backend']}, {info['cpu_usable']} cores); "
        "markers: o coarse, s medium, ^ fine (spacing [m] annotated)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write(data: dict, out: Path):
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(data, indent=2) + "\n")
    out.with_suffix(".md").write_text(markdown(data))
    plot(data, out.with_suffix(".png"))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--cases",
        nargs="+",
        default=["dam_break", "hydrostatic", "standing_wave"],
        choices=["dam_break", "hydrostatic", "standing_wave"],
    )
    p.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    p.add_argument(
        "--levels",
        type=int,
        nargs="+",
        default=[0, 1, 2],
        help="resolution levels (0 coarse, 1 medium, 2 fine)",
    )
    p.add_argument("--repeats", type=int, default=3, help="timed calls (best taken)")
    p.add_argument(
        "--max-timed-s",
        type=float,
        default=10.0,
        help="stop timing further calls once one call exceeds this",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output path without extension "
        "(default validation/results/accuracy_vs_cost_<cpu|gpu>)",
    )
    p.add_argument(
        "--merge",
        action="store_true",
        help="merge into an existing JSON at --out (replace matching rows)",
    )
    p.add_argument(
        "--replot",
        action="store_true",
        help="only rewrite the MD and PNG from the existing JSON",
    )
    args = p.parse_args(argv)

    backend = "gpu" if jax.default_backend() == "gpu" else "cpu"
    out = args.out or HERE / "results" / f"accuracy_vs_cost_{backend}"
    if args.replot:
        write(json.loads(out.with_suffix(".json").read_text()), out)
        return

    info = machine_info()
    print(
        f"backend={info['backend']} dtype={info['dtype']} cpus={info['cpu_usable']}",
        flush=True,
    )
    rows, skipped = [], []
    for case_name in args.cases:
        for level in args.levels:
            for solver in args.solvers:
                spacing = SPACINGS[case_name][level]
                t0 = time.perf_counter()
                r = run_case(case_name, solver, spacing, args)
                r["run_started"] = info["date"]
                rows.append(r)
                print(
                    f"{case_name} {solver} l0={spacing:g}: n={r['capacity']} "
                    f"steps={r['n_steps']} err={100 * r['error']:.2f}% "
                    f"run={r['run_s_best']:.2f}s ({r['wall_per_sim_s']:.3g} s/sim-s, "
                    f"{r['ms_per_step']:.2f} ms/step) "
                    f"compile={r['trace_lower_s'] + r['compile_s']:.1f}s {r['result']} "
                    f"[{time.perf_counter() - t0:.0f}s wall]",
                    flush=True,
                )
    for case_name in SPACINGS:
        for level in range(3):
            for solver in SOLVERS:
                if (
                    case_name not in args.cases
                    or level not in args.levels
                    or (solver not in args.solvers)
                ):
                    skipped.append(
                        f"{case_name} {solver} {SPACINGS[case_name][level]:g}"
                    )
    data = {
        "machine": info,
        "settings": {"repeats": args.repeats, "max_timed_s": args.max_timed_s},
        "rows": rows,
        "skipped": skipped,
        "loadavg_1min_end": _loadavg(),
    }
    if args.merge and out.with_suffix(".json").exists():
        old = json.loads(out.with_suffix(".json").read_text())
        key = lambda r: (r["case"], r["solver"], r["spacing"])  # noqa: E731
        new_keys = {key(r) for r in rows}
        merged = [r for r in old["rows"] if key(r) not in new_keys] + rows
        order = {c: i for i, c in enumerate(SPACINGS)}
        merged.sort(
            key=lambda r: (order[r["case"]], -r["spacing"], SOLVERS.index(r["solver"]))
        )
        have = {f"{r['case']} {r['solver']} {r['spacing']:g}" for r in merged}
        data["rows"] = merged
        data["skipped"] = [s for s in skipped if s not in have]
        data["machine"]["merged_runs"] = old["machine"].get("merged_runs", []) + [
            old["machine"]["date"]
        ]
    write(data, out)
    print(f"wrote {out}.json/.md/.png", flush=True)


if __name__ == "__main__":
    main()
