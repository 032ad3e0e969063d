"""Seed 000's trends for a tsunami carrying an unmoored ship over a quay
(`scenes.tsunami_quay`, 2-D cross-section, prototype scale), measured at the
coarsest resolution that puts 8 particles across the light draft (l0 = 0.5 m).

Groups (each a set of runs of the scene with its defaults except as listed):
  height    tsunami height eta = 8.5 / 13.5 / 18.0 m (seed 000 §4.1: maximum drift
            velocity 8.55 / 13.90 / 17.98 m/s grows with eta);
  draft     drafts 4 and 7 m at eta = 13.5 m (seed Tables 4.2-3..5: heavier ships
            reach their maximum velocity closer to the sea, i.e. after a shorter
            displacement);
  draft_long  drafts 4, 5.5 and 7 m on a quay 300 m long (--t-end 40), where
            the ships' velocity can peak before the quay ends;
  gap       ship-quay distance 2 m, 1.5 B and 2.5 B at eta = 13.5 m, on a sea 90 m
            long (seed §4.3: the ship on the run-up front, at 2 m, drifts
            fastest);
  gap_long  the same on a quay 300 m long (--t-end 40);
  height_ds  the heights with dynamic stabilisation (`scheme="standard_ds"`);
  building  a building 9 m deep, 38 m high, 40 m from the quay edge, hit by the
            tsunami alone and with the ship (seed §5: the impulse with the ship
            exceeds the tsunami-only impulse).
  body      the building hit by a rigid and by an elastic ship, each at three
            largest steps (seed 000 §5: the elastic ship's peak force is lower
            and does not depend on the step);
  building3d  the same in 3-D, in a reduced channel (BUILDING_3D: a 40 m ship,
            a building 12 m long, l / L = 0.3), run at --spacing 2 (2
            particles across the draft: what 2 CPU cores run in about 20 min
            a case; coarser than the 8 across the draft of the 2-D groups).

Our geometry is not the seed's (its sea depth, quay crest and wave series are in
figures only): the sea is 12 m deep, the quay 2 m above it, the wave a long wave
rising over 10 s at the inflow 60 m seaward of the quay edge. The seed's numbers
are reported beside ours for the trends, not as targets. The inflow boundary
absorbs what the quay and the building reflect back to it (the scene's
default; rows measured before commit 7004adf ran a piston, which pumps the
series' discharge in against the reflection: in 2-D a building across the
whole section then dams the sea up towards its roof).

A ship that reaches the quay's landward end falls off it and leaves the domain:
the run stops there (its maximum velocity was reached before).

Each group's trend is checked against the seed's in the results file's
"Trends" section (per group and spacing: the numbers and whether the trend
holds), and the ships' velocities are plotted against their displacement
(results/NAME.png). `--report` rewrites both from the file's rows without
running; `--check` then exits with status 1 if any trend does not hold.

Run: python validation/tsunami_quay.py [--groups height draft gap building]
[--spacing 0.5] [--t-end 25] [--save 0.1] [--every-step] [--fresh]
[--labels LABEL ...] [--out NAME] [--report] [--check] (writes
results/tsunami_quay_cpu.{json,md,png}, or NAME's, after each run, merging rows
run before; runs already there with the same settings are reused unless
--fresh).
"""

import argparse
import json
import time

import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps._result import result_name

SEED_MAX_VELOCITY = {8.5: 8.55, 13.5: 13.90, 18.0: 17.98}  # m/s, seed 000 §4.1
AT_QUAY = 40.0  # m landward of the quay edge: where `u_at_quay` is read
# The building's force averaged over these windows [s]: an impact's peak in a
# single step scales with the step (the contact stops the hull within a step
# or two), its mean over a fixed time does not (seed 000 §3.2.3).
WINDOWS = (0.01, 0.05)
# The reduced 3-D channel of benchmarks/tsunami_cost.py (a 40 m ship in a 60 m
# channel) with a building 12 m long on its centre line: l / L = 0.3, the ratio
# at which seed 000 §5 found the impulse with the ship about 4 times the
# tsunami's alone.
BUILDING_3D = dict(
    dim=3,
    sea_length=40.0,
    quay_length=60.0,
    ship_length=40.0,
    width=60.0,
    gauges=2,
    gauge_spacing=6.0,
    offshore_gauge=20.0,
    tsunami_height=13.5,
    building_depth=9.0,
    building_length=12.0,
    building_distance=30.0,
)


def runs(group: str) -> list[tuple[str, dict]]:
    """(label, overrides) of a group."""
    if group == "height":
        return [(f"eta {eta}", dict(tsunami_height=eta)) for eta in (8.5, 13.5, 18.0)]
    if group == "draft":
        return [
            (f"draft {d}", dict(tsunami_height=13.5, ship_draft=d)) for d in (4.0, 7.0)
        ]
    if group == "draft_long":
        # The draft group on a quay 300 m long: at 100 m the deeper ship is still
        # speeding up where the quay ends, so where its velocity peaks is not
        # seen (run it with --t-end 40: the wave holds for 20 s).
        return [
            (
                f"draft {d}, quay 300 m",
                dict(tsunami_height=13.5, ship_draft=d, quay_length=300.0),
            )
            for d in (4.0, 5.5, 7.0)
        ]
    if group == "gap":
        # A sea 90 m long, so that the ship fits at 2.5 B off the quay.
        return [
            (f"gap {name}", dict(tsunami_height=13.5, ship_gap=gap, sea_length=90.0))
            for name, gap in (("2 m", 2.0), ("1.5 B", 25.5), ("2.5 B", 42.5))
        ]
    if group == "height_ds":
        # The height group with dynamic stabilisation: at l0 = 0.5 m the default
        # scheme's eta = 18 m run stopped at 11.8 s (the breaking bore over the
        # quay threw particles at hundreds of m/s, pressures to 1e8-1e9 Pa).
        return [
            (
                f"eta {eta}, standard_ds",
                dict(tsunami_height=eta, scheme="standard_ds"),
            )
            for eta in (18.0, 8.5, 13.5)
        ]
    if group == "gap_long":
        # The gap group on a quay 300 m long (--t-end 40): the farther ships
        # were still speeding up where the 100 m quay ends.
        return [
            (f"{label}, quay 300 m", {**overrides, "quay_length": 300.0})
            for label, overrides in runs("gap")
        ]
    if group == "building":
        building = dict(tsunami_height=13.5, building_depth=9.0, quay_length=100.0)
        return [
            ("building, ship", building),
            ("building, no ship", {**building, "ship": False}),
        ]
    if group == "body":
        # Rigid against elastic ship at the building, each at three largest
        # steps: the elastic ship's coupling limit (4.33 ms at l0 = 1 m), half
        # of it and less than half again (its sub-step limit, about 2.2 ms,
        # sets its mean step at the first two).
        building = dict(tsunami_height=13.5, building_depth=9.0, quay_length=100.0)
        return [
            (
                f"building, {body} ship, dt_max {dt * 1e3:.2f} ms",
                {**building, "ship_body": body, "dt_max": dt},
            )
            for body in ("rigid", "elastic")
            for dt in (4.3e-3, 2.15e-3, 1.0e-3)
        ]
    if group == "building3d":
        return [
            ("3-D building, ship", BUILDING_3D),
            ("3-D building, no ship", {**BUILDING_3D, "ship": False}),
        ]
    raise ValueError(f"unknown group {group!r}")


def run_saving(case, observe, t_end: float, save: float, every_step: bool):
    """Run the case to `t_end`, observing every `save` seconds or (`every_step`)
    after every step, in chunks of steps, so that an impact's force peak and
    impulse are not sampled at a coarse interval (the last chunk runs on past
    `t_end`; its steps after it are not counted). Returns (saved histories up
    to where the run got, end time [s], steps to it, result, wall time [s])."""
    start = time.perf_counter()
    if not every_step:
        times = np.arange(1, round(t_end / save) + 1) * save
        run = jaxmps.simulate(
            case.scene,
            case.params,
            case.state,
            times=times,
            observe=observe,
            throw=False,
        )
        saved = {k: np.asarray(v) for k, v in run.saved.items()}
        state, result = run.state, run.result
    else:
        state, chunks, result = case.state, [], jaxmps.Result.successful
        while float(state.time) < t_end - 1e-9 and result == jaxmps.Result.successful:
            run = jaxmps.simulate(
                case.scene, case.params, state, 100, 1, observe, throw=False
            )
            chunks.append({k: np.asarray(v) for k, v in run.saved.items()})
            state, result = run.state, run.result
        saved = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    wall = time.perf_counter() - start
    # A run that stops early (throw=False) repeats its last state in the saves
    # after it: keep only the saves it reached (and, saving every step, those
    # up to t_end).
    t = saved["time"]
    keep = (t <= float(state.time) + 1e-6) & (t <= t_end + 1e-6)
    keep &= np.concatenate([[True], np.diff(t) > 0])
    saved = {k: v[keep] for k, v in saved.items()}
    steps = len(saved["time"]) if every_step else int(state.step)
    ended = min(float(state.time), float(saved["time"][-1]))
    return saved, ended, steps, result, wall


def measure(
    label: str,
    overrides: dict,
    spacing: float,
    t_end: float,
    save: float = 0.1,
    every_step: bool = False,
) -> dict:
    """Run one case; its maximum drift velocity, where and when, and the
    building's force peak and impulse."""
    settings = dict(spacing=spacing, t_end=t_end, quay_length=150.0)
    case = jaxmps.scenes.tsunami_quay(**{**settings, **overrides})
    observe = jaxmps.scenes.observe_probes(case.probes)
    saved, ended, steps, result, wall = run_saving(
        case, observe, t_end, save, every_step
    )
    t = saved["time"]
    u = saved.get("ship_u", np.zeros_like(t))
    peak = int(np.argmax(u))
    c = case.config
    x0 = c["quay_edge"] - c["ship_gap"] - 0.5 * c["ship_beam"]
    row = dict(
        label=label,
        overrides=overrides,
        spacing=spacing,
        t_end=t_end,
        save=save,
        every_step=every_step,
        result=result_name(result),
        ended_s=ended,
        steps=steps,
        wall_s=round(wall, 1),
        # rows merge across runs of this script: each keeps the code it ran
        commit=machine_info()["git_commit"],
        particles=int(case.state.active.sum()),
        max_fluid=int(saved["fluid_count"].max()),
        max_drift_velocity=float(u[peak]),
        time_of_max=float(t[peak]),
        # The maximum is the run's last sample when the ship was still speeding
        # up as it left the quay's end.
        max_at_end=bool(peak == len(t) - 1),
        displacement_at_max=float(saved.get("ship_x", t + x0)[peak] - x0),
        max_sea_level=float(saved["sea_level"].max()),
        max_quay_depth_1=float(saved["quay_depth_1"].max()),
        max_quay_u_1=float(saved["quay_u_1"].max()),
    )
    if "ship_x" in saved:
        # Comparable across cases whatever ends the run: the ship's velocity as
        # its centre passes AT_QUAY metres landward of the quay edge.
        onto = saved["ship_x"] - c["quay_edge"]
        passed = np.flatnonzero(onto >= AT_QUAY)
        if passed.size:
            row["u_at_quay"] = float(u[passed[0]])
            row["t_at_quay"] = float(t[passed[0]])
        # The stored series at the save interval (saved every step, sampled).
        grid = np.arange(1, int(t[-1] / save + 1e-6) + 1) * save
        grid = t if not every_step else grid[grid >= t[0]]
        row["series"] = {
            "time": grid.tolist(),
            "ship_x": np.interp(grid, t, saved["ship_x"]).tolist(),
            "ship_u": np.interp(grid, t, u).tolist(),
        }
    if "building_force" in saved:
        force = saved["building_force"]
        row["building_peak_force"] = float(force.max())
        row["building_impulse"] = float(np.trapezoid(force, t))
        if every_step:
            row["building_window_peaks"] = {
                f"{w:g}": window_peak(t, force, w) for w in WINDOWS
            }
    return row


def window_peak(t: np.ndarray, force: np.ndarray, window: float) -> float:
    """The largest mean of `force` over `window` seconds: the impulse gained
    over each window ending at a save, divided by its length (steps vary)."""
    impulse = np.concatenate(
        [[0.0], np.cumsum(0.5 * (force[1:] + force[:-1]) * np.diff(t))]
    )
    ends = t >= t[0] + window
    if not ends.any():
        return float("nan")
    before = np.interp(t[ends] - window, t, impulse)
    return float(((impulse[ends] - before) / window).max())


def table(rows: list[dict]) -> str:
    lines = [
        "| case | l0 [m] | max drift velocity [m/s] (seed) | at t [s] |"
        " displacement at max [m] | u 40 m onto the quay [m/s] (at t [s]) |"
        " building peak [kN/m; 3-D kN] |"
        f" over {' / '.join(f'{w * 1e3:g}' for w in WINDOWS)} ms |"
        " impulse [kN s/m; 3-D kN s] |"
        " saved | run to [s] | steps | mean step [ms] | wall [s] | commit |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        eta = r["overrides"].get("tsunami_height")
        seed = SEED_MAX_VELOCITY.get(eta) if r["label"].startswith("eta") else None
        shown = f"{r['max_drift_velocity']:.2f}" + (f" ({seed})" if seed else "")
        if r.get("max_at_end") or r["time_of_max"] >= r["ended_s"] - 0.1:
            shown += (
                ", still rising at the quay's end"
                if r["result"] == "left_domain"
                else ", still rising when the run stopped"
            )
        at = r.get("u_at_quay")
        at = "" if at is None else f"{at:.2f} ({r['t_at_quay']:.1f})"
        peak = r.get("building_peak_force")
        impulse = r.get("building_impulse")
        ended = "" if r["result"] == "successful" else f" ({r['result']})"
        saves = "every step" if r.get("every_step") else f"{r.get('save', 0.1)} s"
        windows = r.get("building_window_peaks")
        windows = (
            ""
            if windows is None
            else " / ".join(f"{windows[f'{w:g}'] / 1e3:.0f}" for w in WINDOWS)
        )
        lines.append(
            f"| {r['label']} | {r['spacing']} | {shown} | {r['time_of_max']:.1f} | "
            f"{r['displacement_at_max']:.1f} | {at} | "
            f"{'' if peak is None else f'{peak / 1e3:.0f}'} | {windows} | "
            f"{'' if impulse is None else f'{impulse / 1e3:.0f}'} | "
            f"{saves} | "
            f"{r['ended_s']:.1f}{ended} | {r['steps']} | "
            f"{r['ended_s'] / max(r['steps'], 1) * 1e3:.2f} | {r['wall_s']:.0f} | "
            f"{r.get('commit', '')} |"
        )
    if any("commit" not in r for r in rows):
        lines += [
            "",
            "A row with no commit was measured before the rows recorded theirs "
            "(its date is in this file's git history).",
        ]
    return "\n".join(lines)


VERDICT = {True: "holds", False: "**does not hold**", None: "cannot tell"}
# Two maxima closer than this share are not told apart: the 2 m and 1.5 B ships
# at l0 = 0.5 m, run on quays of 150 and 300 m, moved at speeds 0.1-5.7 % apart
# at the same times before the quay's end could reach them (10-14 s), so one
# case's maximum moves by about that much between runs that differ only beyond
# where the flow has got.
TOLD_APART = 0.02


def _rising(r: dict) -> bool:
    """The run's maximum velocity was its last sample: it may be higher still."""
    return bool(r.get("max_at_end")) or r["time_of_max"] >= r["ended_s"] - 0.1


def _body_trend(rows: list[dict], spacing: float) -> list[tuple[str, bool, str]]:
    """The body group's trend (`trends`): rigid against elastic ship at the
    building, at each of the same largest steps."""
    by = {}
    for r in rows:
        if "building_peak_force" in r:
            by.setdefault(r["overrides"]["ship_body"], {})[r["overrides"]["dt_max"]] = r
    if set(by) != {"rigid", "elastic"} or set(by["rigid"]) != set(by["elastic"]):
        return []
    steps = sorted(by["rigid"])

    def peak(r):
        w = r.get("building_window_peaks")
        return r["building_peak_force"] if w is None else w[f"{WINDOWS[0]:g}"]

    rigid = [peak(by["rigid"][dt]) for dt in steps]
    elastic = [peak(by["elastic"][dt]) for dt in steps]
    spread = [max(v) / min(v) for v in (rigid, elastic)]
    return [
        (
            f"body, l0 {spacing} m: the elastic ship's peak force on the"
            " building is lower than the rigid one's at every step and"
            " moves less with the step (seed 000 §5)",
            bool(np.all(np.array(elastic) < rigid) and spread[1] < spread[0]),
            "dt_max "
            + " / ".join(f"{dt * 1e3:.2f}" for dt in steps)
            + " ms: rigid "
            + " / ".join(f"{v / 1e3:.0f}" for v in rigid)
            + ", elastic "
            + " / ".join(f"{v / 1e3:.0f}" for v in elastic)
            + f" kN/m (max/min {spread[0]:.2f} / {spread[1]:.2f})",
        )
    ]


def trends(rows: list[dict]) -> list[tuple[str, bool | None, str]]:
    """Each group's trend against the seed's, per spacing: (title, holds, the
    numbers); holds is None where the runs did not get far enough to tell, or
    (the ship-quay distance) where the two fastest are within TOLD_APART. A
    maximum that was still rising when its run stopped is marked (*): the trend
    is read from it as it stands."""

    def speeds(rs, key="max_drift_velocity"):
        return ", ".join(
            f"{r['label']} {r[key]:.2f}{' (*)' if _rising(r) else ''}" for r in rs
        )

    out = []
    for spacing in sorted({r["spacing"] for r in rows}):
        at = [r for r in rows if r["spacing"] == spacing]

        def group(name, rs=at):
            return [r for r in rs if r.get("group") == name]

        for name in ("height", "height_ds"):
            rs = sorted(group(name), key=lambda r: r["overrides"]["tsunami_height"])
            if len(rs) >= 2:
                u = [r["max_drift_velocity"] for r in rs]
                out.append(
                    (
                        f"{name}, l0 {spacing} m: the maximum drift velocity grows"
                        " with the tsunami height (seed 8.55 / 13.90 / 17.98 m/s)",
                        bool(np.all(np.diff(u) > 0)),
                        speeds(rs) + " m/s",
                    )
                )
        for name in ("draft", "draft_long"):
            rs = sorted(group(name), key=lambda r: r["overrides"]["ship_draft"])
            if len(rs) >= 2:
                d = [r["displacement_at_max"] for r in rs]
                out.append(
                    (
                        f"{name}, l0 {spacing} m: a heavier ship reaches its maximum"
                        " velocity after a shorter displacement (seed Tables 4.2-3..5)",
                        bool(np.all(np.diff(d) < 0)),
                        speeds(rs, "displacement_at_max") + " m",
                    )
                )
        for name in ("gap", "gap_long"):
            rs = group(name)
            if len(rs) >= 2:
                u = np.asarray([r["max_drift_velocity"] for r in rs])
                front = [r["overrides"]["ship_gap"] for r in rs]
                holds, told = bool(front[int(np.argmax(u))] == min(front)), ""
                top = np.sort(u)[::-1]
                if top[0] - top[1] < TOLD_APART * top[1]:
                    holds = None
                    told = f"; the two fastest within {TOLD_APART:.0%}, not told apart"
                out.append(
                    (
                        f"{name}, l0 {spacing} m: the ship on the run-up front (2 m"
                        " off the quay) drifts fastest (seed §4.3)",
                        holds,
                        speeds(rs) + " m/s" + told,
                    )
                )
        for name in ("building", "building3d"):
            rs = {r["overrides"].get("ship", True): r for r in group(name)}
            if True in rs and False in rs and "building_impulse" in rs[True]:
                title = (
                    f"{name}, l0 {spacing} m: the building's impulse with the ship"
                    " exceeds the tsunami's alone (seed: up to about 4x)"
                )
                alone = rs[False]["building_impulse"]
                if alone > 0:
                    ratio = rs[True]["building_impulse"] / alone
                    out.append((title, bool(ratio > 1), f"ratio {ratio:.2f}"))
                else:
                    stopped = " / ".join(
                        f"{r['ended_s']:.1f} s ({r['result']})" for r in rs.values()
                    )
                    out.append(
                        (title, None, f"no impulse yet: the runs stopped at {stopped}")
                    )
        out += _body_trend(group("body"), spacing)
    return out


def plot(rows: list[dict], path) -> None:
    """Each group's ships: velocity against displacement, one panel per group
    and spacing."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = sorted(
        {(r.get("group", "?"), r["spacing"]) for r in rows if "series" in r}
    )
    if not panels:
        return
    cols = min(3, len(panels))
    fig, axes = plt.subplots(
        -(-len(panels) // cols),
        cols,
        figsize=(4.5 * cols, 3.4 * -(-len(panels) // cols)),
        squeeze=False,
    )
    for ax, (name, spacing) in zip(axes.flat, panels):
        for r in rows:
            if r.get("group") == name and r["spacing"] == spacing and "series" in r:
                x = np.asarray(r["series"]["ship_x"])
                ax.plot(x - x[0], r["series"]["ship_u"], label=r["label"], lw=1)
        ax.set_title(f"{name}, l0 = {spacing} m", fontsize=9)
        ax.set_xlabel("ship displacement [m]")
        ax.set_ylabel("ship velocity [m/s]")
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path.with_suffix(".png"), dpi=100)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--groups", nargs="+", default=["height", "draft"])
    parser.add_argument("--spacing", type=float, default=0.5)
    parser.add_argument("--t-end", type=float, default=25.0)
    parser.add_argument("--save", type=float, default=0.1, help="probe interval [s]")
    parser.add_argument("--fresh", action="store_true")
    parser.add_argument(
        "--every-step",
        action="store_true",
        help="observe after every step (an impact's force peak and impulse)",
    )
    parser.add_argument(
        "--labels", nargs="+", default=None, help="only these runs of the groups"
    )
    parser.add_argument("--out", default="tsunami_quay_cpu", help="results name")
    parser.add_argument(
        "--report",
        action="store_true",
        help="rewrite the results table, trends and plot from the file; run nothing",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="with --report: exit with status 1 if any trend does not hold",
    )
    args = parser.parse_args()
    path = HERE / "results" / args.out
    old = []
    if path.with_suffix(".json").exists():
        old = json.loads(path.with_suffix(".json").read_text())["rows"]
    if args.report:
        stored = json.loads(path.with_suffix(".json").read_text())
        write(path, old, [], args, info=stored["machine"])
        failed = [title for title, holds, _ in trends(old) if holds is False]
        for title in failed:
            print(f"does not hold: {title}")
        raise SystemExit(1 if args.check and failed else 0)
    rows = []
    # Runs already in the file at this spacing and end time are reused (--fresh:
    # run them again).
    measured = {
        json.dumps(r["overrides"], sort_keys=True): r
        for r in old
        if r["spacing"] == args.spacing
        and r.get("t_end") == args.t_end
        and r.get("every_step", False) == args.every_step
        and not args.fresh
    }
    for group in args.groups:
        for label, overrides in runs(group):
            if args.labels is not None and label not in args.labels:
                continue
            # A run another group already made (the same settings) is reused.
            key = json.dumps(overrides, sort_keys=True)
            if key not in measured:
                measured[key] = measure(
                    label,
                    overrides,
                    args.spacing,
                    args.t_end,
                    args.save,
                    args.every_step,
                )
            row = {**measured[key], "group": group, "label": label}
            print(json.dumps(row), flush=True)
            rows.append(row)
            write(path, old, rows, args)


def write(path, old: list[dict], rows: list[dict], args, info=None) -> None:
    """The results so far, merged with the file's rows not re-measured. With
    `info` (the machine the file's rows were measured on) only the report is
    rewritten, not the rows."""
    done = {(r["label"], r["spacing"]) for r in rows}
    rows = [r for r in old if (r["label"], r["spacing"]) not in done] + rows
    if info is None:
        info = machine_info()
        path.with_suffix(".json").write_text(
            json.dumps({"machine": info, "args": vars(args), "rows": rows}, indent=1)
        )
    checks = "\n".join(
        f"- {VERDICT[holds]}: {title}. {numbers}."
        for title, holds, numbers in trends(rows)
    )
    path.with_suffix(".md").write_text(
        "# Tsunami over a quay carrying a ship: seed 000's trends (prototype "
        "scale; forces per metre in 2-D, N in 3-D)\n\n"
        f"Machine: {info}\n\n" + table(rows) + "\n\n## Trends\n\n"
        "(*): the run's last sample; the ship was still speeding up when it "
        "stopped.\n\n" + checks + "\n"
    )
    plot(rows, path)


if __name__ == "__main__":
    main()
