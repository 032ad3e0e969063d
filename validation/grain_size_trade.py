"""The speed/accuracy trade of the grain size: one granular column collapse
(`granular_collapse.py`'s case, L0 = 5 cm, a = H0 / L0 = 3, mu = 0.5) with grains
of 10, 5 and 2.5 mm (5, 10 and 20 across the column), a few packings each.

The published runout law (Lube et al. 2005, 1.9 a^(2/3) for a > 2.8) holds for
grains much smaller than the column; each halving of the grain size costs ~4x
the grains in 2-D and more steps (the contact time step falls with the grain's
mass). The table gives, per size: the grains, the DEM sub-steps per fluid step,
steps, wall time per run and per grain-step, the normalised runout against the
law (mean and spread over packings), where 95 % of the grains' volume lies
(the bulk, blind to the front's single grains) and the deposit's angle.

Run: python validation/grain_size_trade.py [--sizes 0.01,0.005,0.0025]
[--seeds 0,1] [--aspect 3] [--rolling 0] [--restitution 0.1] [--x64]
[--floor-spacing M] [--contact-capacity K] [--out NAME]
(writes results/grain_size_trade_cpu.{md,json}, keeping the runs not repeated)
"""

import argparse
import json

import jax
import numpy as np
from _common import HERE, machine_info
from granular_collapse import WIDTH, lube, run


def table(runs: list[dict], info: dict) -> str:
    lines = [
        "# Granular column collapse: the speed/accuracy trade of the grain size",
        "",
        f"Machine: {info}",
        "",
        f"L0 = {WIDTH * 100:g} cm; each row the mean (+- std) over packings "
        "(`seed`). Law: Lube et al. (2005) as quoted by Lagree, Staron & Popinet "
        "(2011), 1.9 a^(2/3) for a > 2.8. Floor: the spacing of its wall "
        "particles (d: the grains' size, the floor as rough as the grains are "
        "large). Grain-steps: grains x steps (the DEM's "
        "sub-steps not counted).",
        "",
        "| grain [mm] | across L0 | a | mu | mu_r | e | float | floor [mm] | grains | "
        "DEM sub-steps | packings | (L-L0)/L0 | law | ratio | bulk (x95-L0)/L0 | "
        "angle [deg] | at rest | steps | wall per run [s] | us per grain-step |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def group(r):
        floor = r.get("floor_spacing", r["spacing"])
        fixed = 0.0 if floor == r["spacing"] else floor  # 0: the grains' size
        return (r["rolling"], r.get("restitution", 0.1), r.get("bits", 32), fixed)

    for (roll, e, bits, floor), d in sorted(
        {(group(r), r["spacing"]) for r in runs}, key=lambda k: (k[0], -k[1])
    ):
        sel = [
            r for r in runs if (group(r), r["spacing"]) == ((roll, e, bits, floor), d)
        ]
        bulk = np.array([r.get("bulk_reach", np.nan) for r in sel])
        bulk_text = (
            "-"
            if np.isnan(bulk).all()
            else f"{np.nanmean(bulk):.2f} +- {np.nanstd(bulk):.2f}"
            + ("" if not np.isnan(bulk).any() else f" ({np.sum(~np.isnan(bulk))})")
        )
        first = sel[0]
        runout = np.array([r["normalised_runout"] for r in sel])
        angle = np.array([r["angle_deg"] for r in sel])
        law = lube(first["aspect"])
        steps = np.mean([r["steps"] for r in sel])
        wall = np.mean([r["wall_s"] for r in sel])
        per = 1e6 * wall / (steps * first["grains"])
        lines.append(
            f"| {d * 1e3:g} | {WIDTH / d:.0f} | {first['aspect']:g} | "
            f"{first['friction']:g} | {roll:g} | {e:g} | {bits} | "
            f"{'d' if not floor else f'{floor * 1e3:g}'} | {first['grains']} | "
            f"{first['substeps']} | "
            f"{len(sel)} | {runout.mean():.2f} +- {runout.std():.2f} | "
            f"{'-' if law is None else f'{law:.2f}'} | "
            f"{'-' if law is None else f'{runout.mean() / law:.2f}'} | "
            f"{bulk_text} | "
            f"{np.nanmean(angle):.1f} +- {np.nanstd(angle):.1f} | "
            f"{'yes' if all(r['settled'] for r in sel) else 'no'} | {steps:.0f} | "
            f"{wall:.0f} | {per:.1f} |"
        )
    return "\n".join(lines) + "\n"


def key(row: dict) -> tuple:
    defaults = {"bits": 32, "restitution": 0.1, "floor_spacing": row["spacing"]}
    return tuple(
        row.get(k, defaults.get(k))
        for k in (
            "aspect",
            "friction",
            "rolling",
            "restitution",
            "spacing",
            "seed",
            "bits",
            "floor_spacing",
        )
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="0.01,0.005,0.0025")
    parser.add_argument("--seeds", default="0,1")
    parser.add_argument("--aspect", type=float, default=3.0)
    parser.add_argument("--friction", type=float, default=0.5)
    parser.add_argument("--rolling", type=float, default=0.0)
    parser.add_argument("--t-end", type=float, default=1.5)
    parser.add_argument("--restitution", type=float, default=0.1)
    parser.add_argument("--x64", action="store_true", help="run in float64")
    parser.add_argument(
        "--floor-spacing",
        type=float,
        default=None,
        help="spacing of the floor's wall particles [m] (default: the grain size)",
    )
    parser.add_argument(
        "--contact-capacity",
        type=int,
        default=None,
        help="DEM contact slots per grain (grains smaller than the floor's "
        "particles have more candidates)",
    )
    parser.add_argument("--out", default="grain_size_trade_cpu")
    args = parser.parse_args()
    if args.x64:
        jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / args.out
    # Runs already in the file are kept; one measured again is replaced.
    runs = []
    if path.with_suffix(".json").exists():
        runs = json.loads(path.with_suffix(".json").read_text())["runs"]
    for d in [float(v) for v in args.sizes.split(",")]:
        for seed in [int(v) for v in args.seeds.split(",")]:
            row = run(
                args.aspect,
                args.friction,
                args.t_end,
                seed,
                args.rolling,
                spacing=d,
                restitution=args.restitution,
                floor_spacing=args.floor_spacing,
                contact_capacity=args.contact_capacity,
            )
            row["machine"] = machine_info()
            row["bits"] = 64 if args.x64 else 32
            runs = [r for r in runs if key(r) != key(row)] + [row]
            print(json.dumps({k: v for k, v in row.items() if "history" not in k}))
            info = machine_info()
            path.with_suffix(".md").write_text(table(runs, info))
            path.with_suffix(".json").write_text(
                json.dumps({"machine": info, "runs": runs}, indent=1)
            )


if __name__ == "__main__":
    main()
