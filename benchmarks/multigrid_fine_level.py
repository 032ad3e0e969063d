"""The multigrid preconditioner's particle level, added or smoothed: the
semi-implicit step's cost and its CG iterations either way.

`Multigrid(fine="additive")` (the default) adds a Jacobi step on the particles
to the cells' V-cycle correction, z = D^-1 r + P C P^T r, with no product with
the particle matrix inside the preconditioner; `fine="multiplicative"` smooths
the particles around the correction like the cell levels (two products per
application). For each case the two scenes are rolled out from the same state,
compiled side by side in one process and timed in alternation (`--rounds`), so
that a host's slow spells fall on both: the ratio per round is the measure.

Run: python benchmarks/multigrid_fine_level.py [--cases dam_break:25k ...]
[--dtype float64] [--rounds 9] (writes results/multigrid_fine_level_<backend>.
{json,md}; a case is scene[:particles], particles of the 2-D dam break as in
side_by_side.py: 7k or 25k; a `sloshing_tank` case runs from t = 1 s)
"""

import argparse
import time

import equinox as eqx
import jax
import numpy as np
from _common import fixed_steps, iteration_stats, write_rows

COLUMN = 0.146  # m, the dam break's column width (side_by_side.py)
ACROSS = {"7k": 56, "25k": 105, "90k": 200}


def build(case: str):
    import jaxmps

    name, _, size = case.partition(":")
    if name == "dam_break":
        made = jaxmps.scenes.dam_break(spacing=COLUMN / ACROSS[size or "25k"])
        return fixed_steps(made), 0.2
    return fixed_steps(getattr(jaxmps.scenes, name)()), 1.0


def measure(case: str, steps: int, rounds: int) -> dict:
    import jaxmps
    from jaxmps.fluid import Multigrid

    made, start = build(case)
    scene, params = made.scene, made.params
    n = int(round(start / float(params.dt)))
    state = jaxmps.simulate(scene, params, made.state, n, 1).state
    scenes = {
        fine: eqx.tree_at(
            lambda s: s.solver.preconditioner, scene, Multigrid(fine=fine)
        )
        for fine in ("additive", "multiplicative")
    }
    row = dict(case=case, particles=int(state.active.sum()), steps=steps)
    runs = {}
    for fine, sc in scenes.items():
        run = eqx.filter_jit(
            lambda st, sc=sc: jaxmps.simulate(sc, params, st, steps, steps).state
        )
        begin = time.perf_counter()
        jax.block_until_ready(run(state))
        row[f"{fine}_compile_s"] = time.perf_counter() - begin
        result, iterations, converged = eqx.filter_jit(iteration_stats)(
            sc, params, state, steps
        )
        row[f"{fine}_iterations"] = float(np.mean(iterations))
        row[f"{fine}_converged"] = bool(np.all(converged))
        runs[fine] = run
    times = {fine: [] for fine in runs}
    for _ in range(rounds):
        for fine, run in runs.items():
            begin = time.perf_counter()
            jax.block_until_ready(run(state))
            times[fine].append((time.perf_counter() - begin) / steps * 1e3)
    for fine, ms in times.items():
        row[f"{fine}_ms"] = ms
    ratio = np.array(times["additive"]) / np.array(times["multiplicative"])
    row["ratio_median"] = float(np.median(ratio))
    row["ratio_range"] = [float(ratio.min()), float(ratio.max())]
    print(row, flush=True)
    return row


def markdown(info, rows) -> str:
    lines = [
        "# The multigrid's particle level: added against smoothed",
        "",
        f"Machine: {info.get('cpu_model', info.get('device'))}; {info['dtype']};"
        " `benchmarks/multigrid_fine_level.py`. The semi-implicit step in motion"
        " (the dam break from t = 0.2 s, the sloshing tank from t = 1 s), fixed"
        " steps; both programs compiled in one process and timed in alternation.",
        "",
        "| case | particles | CG iterations per step: additive / multiplicative |"
        " ms/step, median: additive / multiplicative | additive / multiplicative"
        " per round: median (range) | compile [s] |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['particles']} | {r['additive_iterations']:.1f} /"
            f" {r['multiplicative_iterations']:.1f} |"
            f" {np.median(r['additive_ms']):.2f} /"
            f" {np.median(r['multiplicative_ms']):.2f} |"
            f" {r['ratio_median']:.3f} ({r['ratio_range'][0]:.3f}-"
            f"{r['ratio_range'][1]:.3f}) | {r['additive_compile_s']:.1f} /"
            f" {r['multiplicative_compile_s']:.1f} |"
        )
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases", nargs="+", default=["dam_break:7k", "dam_break:25k", "sloshing_tank"]
    )
    parser.add_argument("--dtype", default="float64", choices=["float32", "float64"])
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", args.dtype == "float64")
    rows = [measure(case, args.steps, args.rounds) for case in args.cases]
    write_rows("multigrid_fine_level", args.out, rows, markdown)


if __name__ == "__main__":
    main()
