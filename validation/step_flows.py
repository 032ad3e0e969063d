"""Seed 002's step flows (Ch. 4, Cases 1-1 and 1-2; V1-V3): water enters on a
weir crest 0.1 m long at q = 0.04 m^2/s (4.5 cm deep at 0.8889 m/s), drops
W = 10 cm onto a 2.5 m bed and leaves over a tail weir of 8 cm (the undular
jump) or 6 cm (the submerged jet). Explicit E-MPS as the seed: c = 10 m/s,
dt = 2e-4 s at l0 = 5 mm (the seed's coarser run), nu = 1e-6.

Measured from frames every 0.5 s over the second half of the run (the seed
averages 11 snapshots at t = 20..30 s):
- h_t, the depth at X = 200 cm below the step (volume of a 2 cm strip);
- the time-mean streamwise velocity near the bed (the first 1 cm of water) and
  at the surface (the top 1 cm) in 1 cm bins of X;
- undular L_r: the reach from the step with reverse (negative) near-bed flow;
- submerged L_e: where the jet reattaches, the first X at which the near-bed
  flow turns downstream; submerged L_r: where the surface velocity first
  reaches the cross-sectional mean q / h_t;
- the regime: a surface roller (the surface flow turning upstream within
  50 cm of the step) is the submerged jet, a surface jet over the bed the
  undular jump; also where the jet runs at X = 15 cm (the height of the
  largest mean velocity, as a share of the depth).

Seed (5 mm): undular L_r = 37 cm; submerged L_r = 48, L_e = 18 cm; at 2.5 mm
h_t = 15.5 / 13.0 cm [experiment 16.0 / 13.5].

Run: python validation/step_flows.py [T=30]  (writes results/step_flows_cpu.{json,md});
python validation/step_flows.py --remeasure measures the saved profiles again.
"""

import json
import pathlib
import sys
import time

import numpy as np
from _common import machine_info

import jaxmps
from jaxmps import Kind

HERE = pathlib.Path(__file__).parent
L0, Q, STEP, CREST = 0.005, 0.04, 0.1, 0.1
CASES = {"undular jump (1-1)": 0.08, "submerged jet (1-2)": 0.06}
SEED = {
    "undular jump (1-1)": {"h_t": 15.5, "experiment_h_t": 16.0, "L_r": 37.0},
    "submerged jet (1-2)": {
        "h_t": 13.0,
        "experiment_h_t": 13.5,
        "L_r": 48.0,
        "L_e": 18.0,
    },
}


def run(weir: float, t_end: float) -> dict:
    head = (Q / 1.83) ** (2 / 3)  # a sharp-crested weir's head at q
    case = jaxmps.scenes.flume(
        spacing=L0,
        discharge=Q,
        inflow_depth=0.045,
        crest_length=CREST,
        step_height=STEP,
        bed_length=CREST + 2.5,
        weir_height=weir,
        tail_depth=weir + head,
        solver="explicit",
        sound_speed=10.0,
        dt=2e-4,
        t_end=t_end,
    )
    times = np.arange(0.5, t_end + 1e-9, 0.5)
    start = time.perf_counter()
    out = jaxmps.simulate(case.scene, case.params, case.state, times=times, throw=False)
    wall = time.perf_counter() - start
    late = np.asarray(out.saved.time) >= 0.5 * t_end
    x = np.asarray(out.saved.position)[late]
    u = np.asarray(out.saved.velocity)[late, :, 0]
    fluid = np.asarray(out.saved.active)[late] & (
        np.asarray(case.state.kind)[None] == int(Kind.FLUID)
    )
    bed = -STEP
    X = x[..., 0] - CREST  # distance below the step
    strip = fluid & (np.abs(X - 2.0) < 0.01)
    h_t = float(strip.sum(axis=1).mean() * L0 * L0 / 0.02)
    bins = np.arange(0.0, 1.0 + 1e-9, 0.01)
    near_bed, surface, jet_height = [], [], None
    for a, b in zip(bins[:-1], bins[1:]):
        column = fluid & (X >= a) & (X < b)
        top = np.where(column, x[..., 1], -np.inf).max(axis=1, keepdims=True)
        low = column & (x[..., 1] < bed + 0.01)
        high = column & (x[..., 1] > top - 0.01)
        near_bed.append(float((u * low).sum() / max(low.sum(), 1)))
        surface.append(float((u * high).sum() / max(high.sum(), 1)))
        if a == 0.15:
            heights = x[..., 1][column] - bed
            speeds = u[column]
            layer = np.rint(heights / L0).astype(int)
            mean = np.bincount(layer, speeds) / np.maximum(np.bincount(layer), 1)
            jet_height = float(np.argmax(mean) * L0 / max(heights.max(), L0))
    return {
        "weir_cm": 100 * weir,
        "h_t_cm": round(100 * h_t, 2),
        "jet_height_share": round(jet_height, 3),
        "near_bed_u": [round(v, 4) for v in near_bed[:80]],
        "surface_u": [round(v, 4) for v in surface[:80]],
        "result": str(out.result),
        "particles": int(np.asarray(out.saved.active)[-1].sum()),
        "steps": int(round(t_end / 2e-4)),
        "wall_s": round(wall, 1),
        **measures(near_bed, surface, h_t),
    }


def _durable(u: np.ndarray, start: int = 0, run: int = 5) -> int:
    """The first bin from `start` after which `u` stays >= 0 for `run` bins."""
    for i in range(start, len(u) - run):
        if np.all(u[i : i + run] >= 0):
            return i
    return len(u)


def measures(near_bed, surface, h_t: float) -> dict:
    """The regime and lengths from the mean velocities in 1 cm bins below the
    step: a surface roller (the surface flow turning upstream within 50 cm) is
    the submerged jet, a surface jet over it the undular jump; the bed roller
    L_r, the reach of upstream near-bed flow, ends where the near-bed flow
    turns downstream for good (5 bins), which for the submerged jet is the
    reattachment L_e; its surface roller L_r ends where the surface velocity
    first reaches the mean q / h_t after the roller began."""
    near_bed, surface = np.asarray(near_bed), np.asarray(surface)
    roller = np.nonzero(surface[:50] < 0)[0]
    plunging = len(roller) > 0
    ends = _durable(near_bed, 1)
    reverse = near_bed[:ends] < 0
    bed_roller = float(np.nonzero(reverse)[0].max() + 1) if reverse.any() else 0.0
    surface_roller = float("nan")
    if plunging:
        back = np.nonzero(surface[roller[0] :] >= Q / h_t)[0]
        if len(back):
            surface_roller = float(roller[0] + back[0])
    return {
        "regime": "submerged jet (surface roller)"
        if plunging
        else "undular (surface jet)",
        "bed_roller_L_r_cm": bed_roller,
        "reattachment_L_e_cm": float(ends) if plunging else float("nan"),
        "surface_roller_L_r_cm": surface_roller,
    }


def main() -> None:
    name = HERE / "results" / "step_flows_cpu"
    if sys.argv[1:2] == ["--remeasure"]:  # the saved profiles, measured again
        saved = json.loads(name.with_suffix(".json").read_text())
        t_end, info, rows = saved["t_end"], saved["machine"], saved["rows"]
        for r in rows.values():
            r.update(measures(r["near_bed_u"], r["surface_u"], r["h_t_cm"] / 100))
    else:
        t_end = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
        rows = {name: run(weir, t_end) for name, weir in CASES.items()}
        info = machine_info()
    write(name, t_end, info, rows)


def write(name, t_end: float, info: dict, rows: dict) -> None:
    name.with_suffix(".json").write_text(
        json.dumps(
            {"machine": info, "t_end": t_end, "rows": rows, "seed": SEED}, indent=2
        )
    )
    lines = [
        "# Step flows: the undular jump and the submerged jet (seed 002 Ch. 4, V1-V3)",
        "",
        f"l0 = {L0} m, explicit E-MPS (c = 10 m/s, dt = 2e-4 s), {t_end} s, means "
        f"over {t_end / 2}-{t_end} s. Machine: {info.get('cpu_model', '?')}.",
        "",
        "| case | weir [cm] | h_t [cm] (seed 2.5 mm, exp.) | regime | jet height / "
        "depth at X = 15 cm | bed roller L_r [cm] | L_e [cm] | surface L_r [cm] | "
        "particles | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for case, r in rows.items():
        s = SEED[case]
        lines.append(
            f"| {case} | {r['weir_cm']:g} | {r['h_t_cm']} ({s['h_t']}, "
            f"{s['experiment_h_t']}) | {r['regime']} | {r['jet_height_share']} | "
            f"{r['bed_roller_L_r_cm']} | {r['reattachment_L_e_cm']} | "
            f"{r['surface_roller_L_r_cm']} | {r['particles']} | {r['wall_s']} |"
        )
    lines += [
        "",
        "Seed at 5 mm: undular bed roller L_r = 37 cm; submerged surface L_r = 48 cm, "
        "L_e = 18 cm (experiment: undular L_r > 50, submerged L_e = 20 cm).",
    ]
    name.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
