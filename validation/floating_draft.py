"""Equilibrium draft of a floating box against Archimedes, over density ratio, box
aspect ratio, water depth and resolution, for both solvers (and, with --heads
and --walls, the semi-implicit solver's `surface_head` and wall condition).

Each case is `scenes.floating_box` released at its (lattice-rounded) Archimedes
draft, run for `--settle` seconds, then observed every few steps for `--window`
seconds. Archimedes is checked by mass: the depth of water the box displaces
(the `displaced` probe: the water per unit length in columns far from the box
minus that in the columns under it, which at rest differ by the box's weight
whatever level the free surface is taken at). For comparison, the draft from
the free surface the pressure sees (`surface_left/right`: where the hydrostatic
pressure of a strip 3-8 l0 from each end wall extrapolates to zero) to the box's
bottom face, and from the far surface particles' centres (`level_*` minus l0/2).
Errors are time means over the window, in units of l0 and in mm.

Run: python validation/floating_draft.py [--quick] [--cases NAME ...]
[--spacings L0 ...] [--heads H ...] [--walls hydrostatic zero-gradient] [--merge]
[--hold damped undamped] (writes results/floating_draft_cpu.{json,md}; --quick
runs the 2-D l0 = B/10 and B/20 rows only; --merge keeps the existing file's rows
that were not re-measured; --hold: the explicit water held at rest, the scene's
default `settle_damping`, or ringing.)
"""

import argparse
import itertools
import json
import time

import equinox as eqx
import jax
import numpy as np
from _common import HERE, machine_info

import jaxmps

BOX_WIDTH = 0.2


def case_rows(quick: bool, three_d=(0.02,)):
    """(name, overrides) of the matrix: every density ratio at the default box
    (B = 0.2 m, H = 0.1 m, so B/H = 2) and depth (0.2 m), then aspect ratio B/H
    and depth one at a time, at each spacing; in 3-D (not `quick`) the density
    ratios at the spacings `three_d`."""
    rows = []
    for l0 in (0.02, 0.01) if quick else (0.02, 0.01, 0.005):
        for ratio in (0.3, 0.5, 0.6, 0.8):
            rows.append((f"ratio {ratio}", dict(density_ratio=ratio, spacing=l0)))
        # A box floats upright only where its metacentric height is positive: a
        # square (B/H = 1) for ratios below 0.211 or above 0.789, B/H = 0.5 below
        # 0.044 or above 0.956 (at ratio 0.5 both roll over, as they should).
        rows.append(("B/H 1", dict(density_ratio=0.15, box_height=0.2, spacing=l0)))
        rows.append(("B/H 4", dict(density_ratio=0.5, box_width=0.4, spacing=l0)))
        for depth in (0.1, 0.3):  # 1 and 3 box heights
            rows.append(
                (f"depth {depth}", dict(density_ratio=0.6, depth=depth, spacing=l0))
            )
    if not quick:
        for l0 in three_d:
            for ratio in (0.3, 0.5, 0.6, 0.8):
                rows.append(
                    (f"3-D ratio {ratio}", dict(density_ratio=ratio, spacing=l0, dim=3))
                )
    return rows


WALLS = {"hydrostatic": True, "zero-gradient": False}
BODY_HEADS = {"own": True, "zero": False}


def measure(
    overrides,
    pressure,
    solver,
    settle,
    window,
    saves,
    head=None,
    walls=None,
    sound_speed=None,
    body_head=None,
    damped_hold=True,
):
    case = jaxmps.scenes.floating_box(
        body_pressure=pressure,
        solver=solver,
        t_end=settle,
        sound_speed=sound_speed,
        settle_damping=damped_hold,
        **overrides,
    )
    if head is not None:
        case = eqx.tree_at(lambda c: c.scene.solver.surface_head, case, head)
    if walls is not None:
        case = eqx.tree_at(lambda c: c.scene.solver.dummy_head, case, WALLS[walls])
    if body_head is not None:
        case = eqx.tree_at(
            lambda c: c.scene.solver.body_head, case, BODY_HEADS[body_head]
        )
    c, dt = case.config, float(case.params.dt)
    l0, bh = c["spacing"], c["box_height"]
    settle_steps = round(settle / dt)
    every = max(1, round(window / dt) // saves)
    observe = jaxmps.scenes.observe_probes(case.probes)
    start = time.perf_counter()
    first = jaxmps.simulate(
        case.scene, case.params, case.state, settle_steps, settle_steps
    )
    out = jaxmps.simulate(
        case.scene, case.params, first.state, every * saves, every, observe=observe
    )
    wall = time.perf_counter() - start
    s = {k: np.asarray(v) for k, v in out.saved.items()}
    bottom = s["box_y"] - 0.5 * bh
    surface = 0.5 * (s["surface_left"] + s["surface_right"])
    centres = 0.5 * (s["level_left"] + s["level_right"]) - 0.5 * l0
    target = c["density_ratio"] * bh
    err_displaced = np.mean(s["displaced"]) - target
    err = np.mean(surface - bottom) - target
    err_centres = np.mean(centres - bottom) - target
    return dict(
        solver=solver,
        pressure=pressure,
        surface_head=(
            float(case.scene.solver.surface_head) if solver == "semi_implicit" else None
        ),
        walls=(
            ("hydrostatic" if case.scene.solver.dummy_head else "zero-gradient")
            if solver == "semi_implicit"
            else None
        ),
        body_head=(
            ("own" if case.scene.solver.body_head else "zero")
            if solver == "semi_implicit"
            else None
        ),
        sound_speed=float(case.params.sound_speed) if solver == "explicit" else None,
        settle_s=float(c["settle"]),
        # the explicit hold: its water rings, or is relaxed (`settle_damping`)
        hold=(
            ("damped" if c["settle_damping"] else "undamped")
            if solver == "explicit" and c["settle"] > 0
            else None
        ),
        dim=int(c["dim"]),
        spacing=l0,
        box_over_l0=round(c["box_width"] / l0),
        density_ratio=c["density_ratio"],
        box_height=bh,
        depth=c["depth"],
        displaced_l0=float(err_displaced / l0),
        displaced_mm=float(err_displaced * 1e3),
        displaced_std_l0=float(np.std(s["displaced"]) / l0),
        error_l0=float(err / l0),
        error_mm=float(err * 1e3),
        error_centres_l0=float(err_centres / l0),
        draft_std_l0=float(np.std(surface - bottom) / l0),
        max_heel_deg=float(np.degrees(np.max(np.abs(s["box_angle"])))),
        particles=int(case.state.active.sum()),
        window_s=window,
        steps=settle_steps + every * saves,
        wall_s=wall,
        result=str(out.result),
    )


def markdown(rows, info):
    lines = [
        "# Floating box: equilibrium draft against Archimedes",
        "",
        f"Machine of the last run: {info.get('cpu_model', '?')}; each row names"
        " its host; float64; `validation/floating_draft.py`.",
        "Errors are time means over the window, minus density_ratio x box height.",
        "'displaced': the depth of water the box displaces, counted by mass",
        "(`DisplacedDepth`: far columns minus the columns under the box) - Archimedes",
        "itself, whatever level the free surface is taken at. 'pressure': from the",
        "pressure's free surface (`PressureLevel`) to the box's bottom face.",
        "'centres': from the far surface particles' centres to the bottom face.",
        "head: the semi-implicit solver's `surface_head`; walls: its dummies'",
        "pressure, continued hydrostatically or with a zero gradient (`dummy_head`);",
        "body: the pressure of the box's dry surface particles, the surface head",
        "of the box's own density ('own', `body_head`) or 0 ('zero').",
        "c: the explicit solver's sound speed (10 m/s: the seeds'; otherwise the",
        "floating scenes' default, ten times sqrt(2 g depth)).",
        "settle: seconds the water settled around the box held still before its",
        "release (the scene's `settle`; by default 20 depth / c under the explicit",
        "solver, whose water starts unpressurised; 0: released at once).",
        "hold: how the explicit solver's water was held (undamped: ringing; damped:",
        "its velocities zeroed 16 times per period of the water column, 4 depth / c).",
        "Target: |displaced| <= 0.3 l0, falling in mm with l0. The probe swings by",
        "+-0.4 l0 with the tank's sloshing: a 1 s window's mean can be 0.3 l0 off",
        "a 3 s window's.",
        "",
        "| case | host | solver | head | walls | body | c [m/s] | settle [s] |"
        " hold | dim |"
        " B/l0 |"
        " ratio |"
        " H [m] |"
        " depth [m] |"
        " displaced [l0] | displaced [mm] | pressure [l0] | centres [l0] |"
        " std [l0] | heel [deg] | window [s] | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        "---|---|---|",
    ]
    for r in rows:
        head = "" if r.get("surface_head") is None else f"{r['surface_head']:g}"
        c = "" if r.get("sound_speed") is None else f"{r['sound_speed']:.1f}"
        lines.append(
            f"| {r['case']} | {r.get('host', '?').split(',')[0]} | {r['solver']} |"
            f" {head} | {r.get('walls') or ''} |"
            f" {r.get('body_head') or ''} | {c} | {r.get('settle_s', 0.0):.2g} |"
            f" {r.get('hold') or ''} | {r['dim']} |"
            f" {r['box_over_l0']} | {r['density_ratio']} | {r['box_height']} |"
            f" {r['depth']} | {r['displaced_l0']:+.2f} | {r['displaced_mm']:+.2f} |"
            f" {r['error_l0']:+.2f} | {r['error_centres_l0']:+.2f} |"
            f" {r['displaced_std_l0']:.2f} | {r['max_heel_deg']:.2f} |"
            f" {r.get('window_s', 1.0):g} | {r['wall_s']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def _arguments():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--settle", type=float, default=2.0)
    parser.add_argument("--window", type=float, default=1.0)
    parser.add_argument("--saves", type=int, default=50)
    parser.add_argument("--solvers", nargs="+", default=["semi_implicit", "explicit"])
    parser.add_argument(
        "--heads",
        nargs="+",
        type=float,
        default=[None],
        help="semi-implicit surface_head values (default: the solver's)",
    )
    parser.add_argument(
        "--walls",
        nargs="+",
        choices=sorted(WALLS),
        default=[None],
        help="semi-implicit wall conditions (default: the solver's)",
    )
    parser.add_argument(
        "--merge",
        action="store_true",
        help="keep the existing file's rows that are not measured again",
    )
    parser.add_argument(
        "--sound-speeds",
        nargs="+",
        default=["auto"],
        help="explicit sound speeds [m/s], or 'auto' (the scene's default)",
    )
    parser.add_argument(
        "--body-heads",
        nargs="+",
        choices=sorted(BODY_HEADS),
        default=[None],
        help="semi-implicit body_head: the box's own head or 0 (default: the solver's)",
    )
    parser.add_argument(
        "--hold",
        nargs="+",
        choices=["damped", "undamped"],
        default=["damped"],
        help="explicit: the held water brought to rest or left ringing "
        "(scene `settle_damping`)",
    )
    parser.add_argument("--cases", nargs="*", help="only these case names")
    parser.add_argument("--spacings", nargs="*", type=float, help="only these l0")
    parser.add_argument(
        "--three-d-spacings",
        nargs="+",
        type=float,
        default=[0.02],
        help="l0 of the 3-D rows (0.01, B/20: about an hour a case on one core)",
    )
    parser.add_argument("--out", default="floating_draft_cpu")
    return parser.parse_args()


def main():
    args = _arguments()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / args.out
    old = []
    if args.merge and path.with_suffix(".json").exists():
        stored = json.loads(path.with_suffix(".json").read_text())
        old = stored["rows"]
        for r in old:  # rows from before the choice of wall condition
            r.setdefault("host", stored["machine"].get("cpu_model", "?"))
            r.setdefault("settle_s", 0.0)  # rows from before the held spin-up
            if r["settle_s"] > 0 and r["solver"] == "explicit":
                r.setdefault("hold", "undamped")  # rows before the damped hold
            if r["solver"] == "semi_implicit":
                r.setdefault("walls", "zero-gradient")
                r.setdefault("body_head", "zero")  # before the bodies' head
            else:  # rows from before the depth-derived sound speed
                r.setdefault("sound_speed", 10.0)
    rows = []
    for name, overrides in case_rows(args.quick, args.three_d_spacings):
        if args.cases and name not in args.cases:
            continue
        if args.spacings and overrides["spacing"] not in args.spacings:
            continue
        for solver in args.solvers:
            semi = solver == "semi_implicit"
            heads = args.heads if semi else [None]
            speeds = [None] if semi else args.sound_speeds
            for head, walls, body, speed, hold in itertools.product(
                heads,
                args.walls if semi else [None],
                args.body_heads if semi else [None],
                speeds,
                ["damped"] if semi else args.hold,
            ):
                row = measure(
                    overrides,
                    "fluid",
                    solver,
                    args.settle,
                    args.window,
                    args.saves,
                    head,
                    walls,
                    None if speed in (None, "auto") else float(speed),
                    body,
                    hold == "damped",
                )
                row["case"] = name
                row["host"] = machine_info().get("cpu_model", "?")
                rows.append(row)
                print(json.dumps(row), flush=True)
                merged = [r for r in old if _key(r) not in {_key(n) for n in rows}]
                merged = sorted(merged + rows, key=_order)
                info = machine_info()
                path.with_suffix(".json").write_text(
                    json.dumps({"machine": info, "rows": merged}, indent=1)
                )
                path.with_suffix(".md").write_text(markdown(merged, info))


def _key(row):
    """What identifies a row: its case, solver and settings."""
    return tuple(
        row.get(k)
        for k in (
            "case",
            "solver",
            "surface_head",
            "walls",
            "body_head",
            "sound_speed",
            "settle_s",
            "hold",
            "dim",
            "spacing",
        )
    )


def _order(row):
    """Rows by dimension, coarsest spacing first, then in the matrix's order."""
    names = list(dict.fromkeys(name for name, _ in case_rows(False)))
    return (row["dim"], -row["spacing"], names.index(row["case"]))


if __name__ == "__main__":
    main()
