"""Seed 002's fully coupled Case 3-3 (Ch. 7, V6): five rows of blocks resting on
a movable bed of DEM grains below a groundsill, the bed lowered by 4 cm
downstream, q = 0.006 m^2/s; the jet scours below the last row, bares its face,
and the rows wash out one after another.

The seed (1 mm, 10 s spin-up, 60 s run): just before the first washout (3.2 s)
the hole is L = 11.3 cm long, Z_d = 6.0 cm deep; the last row (row 1) goes at
about 4 s, row 2 at 18.5 s, row 5 at 22.5 s (rows 2-4 as one unit); chaotic
times, the check a cascade. The experiment lost rows 1-4 within 8 s.

Here, at the seed's own 5 mm moving-bed grains (§8.3 Method B: R = 0.25, 1250
kg/m^3, k_n = 323 N/m, Table 8.4) and this repository's 5 mm blocks (2.0 x 1.5
cm at that spacing, mass-matched): the set-up of `notebooks/flume.ipynb`, run
longer. The grains and blocks are held for `--release` s while the flow forms.

Run: PYTHONPATH=. python validation/coupled_washout.py [--release 1] [--main 12]
(writes results/coupled_washout_5mm_cpu.{json,md,png}).
"""

import argparse
import json
import time

import jax
import numpy as np
from _common import HERE, machine_info, result_name
from block_washout import departures, displacements

import jaxmps

jax.config.update("jax_enable_x64", True)

# Seed 002 Ch. 7 (its Fig. 7.2 text): rows counted from downstream, s after release.
SEED_DEPARTURES = {1: 4.0, 2: 18.5, 5: 22.5}
SEED_HOLE = (0.113, 0.060)  # L, Z_d [m] at 3.2 s, just before row 1 goes

SETUP = dict(
    spacing=0.005,
    block_rows=5,
    block_gap=0.0,
    scour_length=0.0,
    scour_depth=0.0,
    scour_exposure=0.0,
    reach_length=0.1,
    movable_length=0.4,
    movable_depth=0.07,
    bed_lowering=0.04,
    bed_length=1.2,
    grain_density=1250.0,
    stiffness=323.0,
)


def run(args) -> dict:
    case = jaxmps.scenes.block_washout(
        **SETUP, release_time=args.release, t_end=args.release + args.main
    )
    n_saves = round((args.release + args.main) / args.every)
    times = np.round(np.arange(1, n_saves + 1) * args.every, 9)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=times,
        observe=jaxmps.scenes.observe_probes(case.probes),
        throw=False,
    )
    wall = time.perf_counter() - start
    after = times - args.release
    moved = displacements(case, out.saved)
    length = float(case.config["block_length"])
    gone = departures(after, moved, length)
    depth = np.asarray(out.saved["scour_depth"])
    hole_length = np.asarray(out.saved["scour_length"])
    first = next((t for t in gone if t is not None), None)
    before = None
    if first is not None:  # the hole one save before the last row left
        i = max(int(np.argmin(np.abs(after - first))) - 1, 0)
        before = dict(
            t=round(float(after[i]), 3),
            length_cm=round(100 * float(hole_length[i]), 2),
            depth_cm=round(100 * float(depth[i]), 2),
        )
    return dict(
        setup=SETUP,
        release=args.release,
        main=args.main,
        result=result_name(out.result),
        particles=int(np.asarray(case.state.active).sum()),
        grains=int(case.state.grains.index.shape[0]),
        steps=int(round((args.release + args.main) / float(case.params.dt))),
        wall_s=round(wall, 1),
        departures=gone,
        seed_departures=SEED_DEPARTURES,
        hole_before_first=before,
        times=[round(float(t), 3) for t in after],
        moved_mm=[[round(1e3 * float(v), 2) for v in row] for row in moved],
        blocks_out=[int(round(float(v))) for v in np.asarray(out.saved["blocks_out"])],
        scour_depth_cm=[round(100 * float(v), 2) for v in depth],
        scour_length_cm=[round(100 * float(v), 2) for v in hole_length],
    )


def markdown(row: dict, info: dict) -> str:
    rows = len(row["departures"])
    lines = [
        "# Coupled washout (seed 002 Ch. 7, Case 3-3): 5 rows on a movable bed, "
        "l0 = 5 mm",
        "",
        f"Spin-up {row['release']:g} s with grains and blocks held, then "
        f"{row['main']:g} s free; {row['particles']:,} particles, "
        f"{row['grains']:,} grains, {row['steps']:,} steps, {row['wall_s']:.0f} s "
        f"wall ({row['result']}). Host: {info['cpu_model']}, float64.",
        "",
        "| row (1 = last) | left after release [s] | seed (1 mm) [s] |",
        "|---|---|---|",
    ]
    for k in range(rows):
        ours = row["departures"][k]
        seed = SEED_DEPARTURES.get(k + 1)
        lines.append(
            f"| {k + 1} | {'-' if ours is None else f'{ours:g}'} | "
            f"{'-' if seed is None else f'{seed:g}'} |"
        )
    hole = row["hole_before_first"]
    lines += [""]
    if hole is not None:
        lines.append(
            f"The hole at {hole['t']:g} s, the save before row 1 left: L = "
            f"{hole['length_cm']:g} cm, Z_d = {hole['depth_cm']:g} cm (seed at 3.2 s: "
            f"{100 * SEED_HOLE[0]:g} / {100 * SEED_HOLE[1]:g} cm)."
        )
    else:
        lines.append("No row left its place.")
    return "\n".join(lines) + "\n"


def plot(row: dict, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(row["times"])
    moved = np.asarray(row["moved_mm"])
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 3.6))
    rows = moved.shape[1]
    for k in range(rows):
        a.plot(t, moved[:, k] / 10, label=f"row {rows - k}")
    for k, s in SEED_DEPARTURES.items():
        a.axvline(s, c="0.6", lw=0.6, ls="--")
    a.set(xlabel="time after release [s]", ylabel="moved [cm]", ylim=(0, 20))
    a.legend(fontsize=8)
    b.plot(t, row["scour_depth_cm"], label="Z_d")
    b.plot(t, row["scour_length_cm"], label="L")
    b.set(xlabel="time after release [s]", ylabel="[cm]", title="scour hole")
    b.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--release", type=float, default=1.0)
    parser.add_argument("--main", type=float, default=12.0)
    parser.add_argument("--every", type=float, default=0.25)
    args = parser.parse_args()
    info = machine_info()
    row = run(args)
    stem = HERE / "results" / "coupled_washout_5mm_cpu"
    stem.with_suffix(".json").write_text(
        json.dumps({"args": vars(args), "machine": info, "run": row}, indent=1)
    )
    stem.with_suffix(".md").write_text(markdown(row, info))
    plot(row, stem.with_suffix(".png"))
    print(markdown(row, info))


if __name__ == "__main__":
    main()
