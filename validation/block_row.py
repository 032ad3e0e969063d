"""A row of PMS blocks on a slope in still water: stick, slip and no toppling.

Two 0.5 m blocks of twice the water's density side by side (`block_stack`,
`layout="row"`) on a floor under gravity tilted to tan(theta) = 0.5, in water
1 m deep, l0 = 0.05 m, each with mu = 0 (the frictionless slide, which measures
the water's added mass), 0.55 (tan theta = 0.91 mu: they must stay) and 0.25
(they slide). Two layouts: touching (`gap=0`: the lower block carries the upper
one's push) and apart (`gap=0.2`). Over 0.5 s: each block's travel, its ratio to
the frictionless slide against the friction share (sin - mu cos) / sin that the
still-water block of seed 002's T10 follows, and the largest tilt.

Options: --t-end (default 0.5 s), --scheme (the scene's `scheme`, default
standard), --out (the results' name, default block_row).

Run: python validation/block_row.py  (writes results/block_row_cpu.{json,md})
     python validation/block_row.py --t-end 2 --scheme standard_ds \
         --out block_row_2s_standard_ds
"""

import argparse
import json
import math
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
TAN = 0.5
MUS = (0.0, 0.55, 0.25)


def run(gap: float, normal: str, t_end: float, scheme: str) -> list[dict]:
    case = jaxmps.scenes.block_stack(
        scheme=scheme,
        friction_normal=normal,
        layout="row",
        blocks=2,
        gap=gap,
        angle=math.degrees(math.atan(TAN)),
        water_depth=1.0,
        floor_length=3.0,
    )
    mus = np.asarray(MUS)
    start = time.perf_counter()
    out = jaxmps.sweep(
        case,
        {
            "rigid.mu_static": np.repeat(mus[:, None], 2, 1),
            "rigid.mu_kinetic": np.repeat(mus[:, None], 2, 1),
        },
        times=np.linspace(t_end / 10, t_end, 10),
    )
    wall = time.perf_counter() - start
    rows = []
    theta = math.atan(TAN)
    for k in range(2):
        x = np.asarray(out.saved[f"block{k}_x"])
        travel = x[:, -1] - x[:, 0] + (x[:, 0] - float(case.state.rigid.centre[k, 0]))
        tilt = np.max(np.abs(np.asarray(out.saved[f"block{k}_angle"])), axis=1)
        for m, mu in enumerate(mus):
            share = (math.sin(theta) - mu * math.cos(theta)) / math.sin(theta)
            rows.append(
                dict(
                    normal=normal,
                    gap=gap,
                    block=k,
                    mu=float(mu),
                    travel_m=float(travel[m]),
                    ratio_to_frictionless=float(travel[m] / travel[0]),
                    friction_share=max(share, 0.0),
                    largest_tilt_deg=float(np.degrees(tilt[m])),
                    result=int(np.asarray(out.result)[m]),
                    wall_s=wall,
                )
            )
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-end", type=float, default=0.5)
    parser.add_argument("--scheme", default="standard")
    parser.add_argument("--out", default="block_row")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    T = args.t_end
    rows = []
    for normal in ("submerged_weight", "reaction"):
        for gap in (0.0, 0.2):
            rows += run(gap, normal, T, args.scheme)
    out = dict(machine=machine_info(), t_end=T, scheme=args.scheme, rows=rows)
    name = f"{args.out}_cpu"
    (HERE / "results" / f"{name}.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# A row of blocks on a slope in still water",
        "",
        "Script: `validation/block_row.py`. Two 0.5 m blocks (2 x the water's "
        f"density) side by side, tan(theta) = {TAN}, water 1 m deep, l0 = 0.05 m, "
        "float64, "
        f"scheme {args.scheme}, {T} s. Travel along the slope; the ratio to the "
        "frictionless slide against the friction share (sin - mu cos) / sin; "
        "the largest tilt.",
        "",
        "| normal force | gap [m] | block | mu | travel [m] | / frictionless | "
        "share | largest tilt [deg] | result |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['normal']} | {r['gap']:g} | {r['block']} | {r['mu']:g} | "
            f"{r['travel_m']:.4f} | "
            f"{r['ratio_to_frictionless']:.3f} | {r['friction_share']:.3f} | "
            f"{r['largest_tilt_deg']:.2f} | {r['result']} |"
        )
    (HERE / "results" / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
