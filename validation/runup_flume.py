"""Seed 000 §3.1: a dam-break bore runs up over a quay onto a building, whose
front face carries pressure gauges H1-H3 0.02 m apart near its base
(`scenes.tsunami_quay` with a reservoir instead of the inflow, no ship, 2-D).

The experiment's geometry as printed: the quay 4.5 m from the gate, the front
water depth 0.2 m, the quay top 0.02 m above it, the building 0.4 m high and
0.12 m deep, at P1 (0.12 m from the quay edge). The reservoir's length and depth
are in the seed's figures only: we take 1.0 m and 0.5 m (a choice).

The seed reports (figures only, no numbers): a double-peak pressure history at
the building, a first impulsive peak as the bore front strikes and a second rise
as the water thrown up the face falls back, and H3 (the highest gauge) lower
than H1 and H2 at the first peak. This script measures both on the pressure
histories saved every `--save` seconds, smoothed over `--smooth` seconds (the
wall pressure of standard MPS is noisy at the 20-50 Hz of its pressure
oscillations): the bore's arrival is the first time the smoothed H1 exceeds 0.3 x
its 99th percentile (isolated splash drops before the bore do not reach that);
first peak: the largest pressure within 0.1 s of the arrival; dip: the lowest
after it within the next 0.3 s; second peak: the largest after the dip up to 1 s
after the arrival. A double peak is counted where the dip is below 0.8 x both
peaks. The raw histories are kept in the JSON file.

Run: python validation/runup_flume.py [--spacing 0.01] [--t-end 3.5]
[--positions 0.12 0.48] [--scheme standard] (writes results/runup_flume_cpu.{json,md}).
"""

import argparse
import json
import time

import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps._result import result_name

FLUME = dict(
    sea_length=4.5,
    sea_depth=0.2,
    quay_crest=0.02,
    quay_length=1.5,
    ship=False,
    building_depth=0.12,
    building_height=0.4,
    pressure_spacing=0.02,
    pressure_gauges=3,
    reservoir_length=1.0,  # not in the text (a choice)
    reservoir_depth=0.5,  # not in the text (a choice)
    offshore_gauge=1.0,
    gauge_spacing=0.06,
    gauges=1,
)


def smooth(series: np.ndarray, width: int) -> np.ndarray:
    if width <= 1:
        return series
    kernel = np.ones(width) / width
    return np.convolve(series, kernel, mode="same")


def peaks(t: np.ndarray, p: np.ndarray, arrival: float) -> dict:
    """The first peak, the dip after it and the second peak (see the module)."""
    first_window = (t >= arrival) & (t <= arrival + 0.1)
    i1 = np.flatnonzero(first_window)[np.argmax(p[first_window])]
    dip_window = (t > t[i1]) & (t <= t[i1] + 0.3)
    i_dip = np.flatnonzero(dip_window)[np.argmin(p[dip_window])]
    second_window = (t > t[i_dip]) & (t <= arrival + 1.0)
    i2 = np.flatnonzero(second_window)[np.argmax(p[second_window])]
    double = p[i_dip] < 0.8 * min(p[i1], p[i2])
    return dict(
        first=float(p[i1]),
        first_t=float(t[i1]),
        dip=float(p[i_dip]),
        dip_t=float(t[i_dip]),
        second=float(p[i2]),
        second_t=float(t[i2]),
        double_peak=bool(double),
    )


def measure(position, spacing, t_end, save, width, scheme):
    case = jaxmps.scenes.tsunami_quay(
        **FLUME, building_distance=position, spacing=spacing, t_end=t_end, scheme=scheme
    )
    observe = jaxmps.scenes.observe_probes(case.probes)
    times = np.arange(1, round(t_end / save) + 1) * save
    start = time.perf_counter()
    run = jaxmps.simulate(
        case.scene, case.params, case.state, times=times, observe=observe, throw=False
    )
    wall = time.perf_counter() - start
    saved = {k: np.asarray(v) for k, v in run.saved.items()}
    t = saved["time"]
    row = dict(
        position=position,
        spacing=spacing,
        scheme=scheme,
        result=result_name(run.result),
        steps=int(run.state.step),
        wall_s=round(wall, 1),
        particles=int(case.state.active.sum()),
        max_sea_level=float(saved["sea_level"].max()),
        max_force=float(saved["building_force"].max()),
        impulse=float(np.trapezoid(saved["building_force"], t)),
        smooth_s=width,
    )
    raw = {f"H{k}": saved[f"building_pressure_{k}"] for k in (1, 2, 3)}
    row.update(analyse(t, raw, save, width))
    series = {"time": t.tolist()}
    for k in (1, 2, 3):
        series[f"H{k}"] = saved[f"building_pressure_{k}"].tolist()
    return row, series


def analyse(t: np.ndarray, raw: dict, save: float, width: float) -> dict:
    """The arrival, the three gauges' peaks and whether H3 < H1, H2 at the first
    peak, from the histories `raw` {"H1": ..., "H2": ..., "H3": ...}."""
    n = max(1, round(width / save))
    gauges = {name: smooth(np.asarray(p), n) for name, p in raw.items()}
    level = 0.3 * np.percentile(gauges["H1"], 99)
    arrival = float(t[np.argmax(gauges["H1"] > level)])
    row = {"arrival": arrival}
    for name, p in gauges.items():
        row[name] = peaks(t, p, arrival)
    row["H3_below_H1_H2_first"] = bool(
        row["H3"]["first"] < min(row["H1"]["first"], row["H2"]["first"])
    )
    return row


def reanalyse(path, save: float, width: float) -> None:
    """Recompute the rows of a results file from its stored histories."""
    data = json.loads(path.read_text())
    for row, series in zip(data["rows"], data["series"]):
        t = np.asarray(series["time"])
        row.update(analyse(t, {k: series[k] for k in ("H1", "H2", "H3")}, save, width))
        row["smooth_s"] = width
    path.write_text(json.dumps(data))
    path.with_suffix(".md").write_text(document(data["rows"], data.get("note", "")))


def key(row: dict) -> tuple:
    return (row["position"], row["spacing"], row["scheme"])


def document(rows: list[dict], note: str) -> str:
    machines = "\n".join(
        f"- P = {r['position']} m, l0 = {r['spacing']} m, {r['scheme']}: {r['machine']}"
        for r in rows
    )
    return (
        "# Dam-break bore on a building on a quay (seed 000 §3.1): pressure "
        f"features\n\n{note}\n\n" + table(rows) + f"\n\nMachines:\n\n{machines}\n"
    )


def table(rows: list[dict]) -> str:
    lines = [
        "| P [m] | l0 [m] | scheme | arrival [s] | H1 first / dip / second [kPa] |"
        " H2 | H3 | double peak (H1,H2,H3) | H3 < H1,H2 first | force max [N/m] |"
        " wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [
            f"{r[h]['first'] / 1e3:.2f} / {r[h]['dip'] / 1e3:.2f} / "
            f"{r[h]['second'] / 1e3:.2f}"
            for h in ("H1", "H2", "H3")
        ]
        doubles = ",".join(
            "y" if r[h]["double_peak"] else "n" for h in ("H1", "H2", "H3")
        )
        lines.append(
            f"| {r['position']} | {r['spacing']} | {r['scheme']} | "
            f"{r['arrival']:.3f} | "
            + " | ".join(cells)
            + f" | {doubles} | {'yes' if r['H3_below_H1_H2_first'] else 'no'} | "
            f"{r['max_force']:.0f} | {r['wall_s']:.0f} |"
        )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacing", type=float, default=0.01)
    parser.add_argument("--t-end", type=float, default=3.5)
    parser.add_argument("--save", type=float, default=0.002)
    parser.add_argument("--smooth", type=float, default=0.02)
    parser.add_argument("--positions", type=float, nargs="+", default=[0.12])
    parser.add_argument("--scheme", default="standard")
    parser.add_argument(
        "--reanalyse", action="store_true", help="recompute the rows from the file"
    )
    args = parser.parse_args()
    path = HERE / "results" / "runup_flume_cpu"
    if args.reanalyse:
        reanalyse(path.with_suffix(".json"), args.save, args.smooth)
        return
    # Rows of other positions, spacings or schemes already in the file are kept
    # (each with the machine it ran on); a row measured again is replaced.
    previous = (
        json.loads(path.with_suffix(".json").read_text())
        if path.with_suffix(".json").exists()
        else {"rows": [], "series": []}
    )
    info = machine_info()
    note = previous.get("note", "")
    kept = {key(r): (r, s) for r, s in zip(previous["rows"], previous["series"])}
    for position in args.positions:
        row, series = measure(
            position, args.spacing, args.t_end, args.save, args.smooth, args.scheme
        )
        row["machine"] = info
        print(json.dumps(row), flush=True)
        kept[key(row)] = (row, series)
        rows = [r for r, _ in kept.values()]
        histories = [s for _, s in kept.values()]
        data = {"note": note, "rows": rows, "series": histories}
        path.with_suffix(".json").write_text(json.dumps(data))
        path.with_suffix(".md").write_text(document(rows, note))


if __name__ == "__main__":
    main()
