"""Stacks of PMS blocks on a slope, dry: do they hold below their coefficient,
and how many sweeps of the friction between bodies does that take?

Blocks 0.5 m wide and 0.25 m tall (`block_stack`, l0 = 0.05 m, dt = 1 ms) on a
2 m base block of the same height (mu = 1.5 against the floor), under gravity
tilted to tan(theta) = 0.6, with mu = 0.66 between the blocks (tan = 0.91 mu):
every block must stay. Cases: one block on the base (a stack of two), two
blocks on it (three), and two 0.5 m square blocks touching side by side on the
floor (a row, mu = 0.55 against the floor, tan = 0.5 = 0.91 mu). For each
`friction_sweeps` value: every block's travel along the slope over 1 s after
the scene's settling and the largest tilt (the sweeps' cost:
benchmarks/rigid_cost.py).

Options: --sweeps (default 1 8 16 32 64 128), --t-end (default 1 s).

Run: python validation/block_stack_sweeps.py
     (writes results/block_stack_sweeps_cpu.{json,md})
"""

import argparse
import json
import math
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
CASES = {
    "stack of two": dict(blocks=2, mu=[1.5, 0.66]),
    "stack of three": dict(blocks=3, mu=[1.5, 0.66, 0.66]),
    "row of two": dict(blocks=2, mu=[0.55, 0.55]),
}


def build(name: str, sweeps: int):
    spec = CASES[name]
    if name.startswith("row"):
        settings = dict(layout="row", gap=0.0, angle=math.degrees(math.atan(0.5)))
    else:
        settings = dict(
            base_width=2.0,
            block_height=0.25,
            dt=0.001,
            angle=math.degrees(math.atan(0.6)),
        )
    case = jaxmps.scenes.block_stack(
        blocks=spec["blocks"], friction_sweeps=sweeps, **settings
    )
    mu = jnp.asarray(spec["mu"], case.params.rigid.mu_static.dtype)
    params = eqx.tree_at(
        lambda p: (p.rigid.mu_static, p.rigid.mu_kinetic), case.params, (mu, mu)
    )
    return case, params


def run(name: str, sweeps: int, t_end: float) -> dict:
    case, params = build(name, sweeps)
    n = round(t_end / float(params.dt))
    out = jaxmps.simulate(
        case.scene, params, case.state, n, n, observe=lambda scene, state: state.rigid
    )
    travel = (
        np.asarray(out.saved.centre)[-1, :, 0]
        - np.asarray(case.state.rigid.centre)[:, 0]
    )
    tilt = np.degrees(np.abs(np.asarray(out.saved.orientation))).max()
    return dict(
        case=name,
        sweeps=sweeps,
        travel_mm=[float(1e3 * t) for t in travel],
        largest_tilt_deg=float(tilt),
        successful=bool(out.result == jaxmps.Result.successful),
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sweeps", type=int, nargs="+", default=[1, 8, 16, 32, 64, 128]
    )
    parser.add_argument("--t-end", type=float, default=1.0)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    rows = [run(name, k, args.t_end) for name in CASES for k in args.sweeps]
    out = dict(machine=machine_info(), t_end=args.t_end, rows=rows)
    (HERE / "results" / "block_stack_sweeps_cpu.json").write_text(
        json.dumps(out, indent=1)
    )
    lines = [
        "# Stacks and rows of blocks on a slope: friction between bodies by sweeps",
        "",
        "Script: `validation/block_stack_sweeps.py`. Dry, l0 = 0.05 m, float64. "
        "Stacks: 0.5 x 0.25 m blocks on a 2 x 0.25 m base (mu = 1.5 on the "
        "floor), tan(theta) = 0.6, mu = 0.66 between blocks, dt = 1 ms. Row: two "
        "0.5 m blocks touching, tan(theta) = 0.5, mu = 0.55. Every block should "
        f"stay. Travel along the slope over {args.t_end} s (lowest block first), "
        "the largest tilt and whether the run succeeded.",
        "",
        "| case | sweeps | travel [mm] | largest tilt [deg] | successful |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        travel = " / ".join(f"{t:.3f}" for t in r["travel_mm"])
        lines.append(
            f"| {r['case']} | {r['sweeps']} | {travel} | "
            f"{r['largest_tilt_deg']:.3f} | {r['successful']} |"
        )
    (HERE / "results" / "block_stack_sweeps_cpu.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
