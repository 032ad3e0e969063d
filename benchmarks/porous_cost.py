"""Cost of porous damping regions as a fraction of step time.

The same case is run with and without its regions: the sloped Tomita tank with
the seed's region of three porous plates (one box), a rectangular sloshing tank
with one, four and sixteen regions, and a 3-D hydrostatic tank with one. Then the
cost of a porosity: hydrostatic tanks (2-D at 1 cm, 3-D at 2 cm) with a region
of porosity 0.9 / 0.85 against the same region without one (its pairs weighed by
the pore weights, the scene on the coupled path). Compile time and run time are
reported separately; run times are the best of seven calls after an untimed one,
the last four taken in turns with the case it is compared with (`taking_turns`),
fixed steps; the CG iterations per step of each are reported beside them.

Run: python benchmarks/porous_cost.py  (writes results/porous_cost_cpu.{json,md})
"""

import json
import pathlib
import time

import jax
import numpy as np
from _common import (
    fixed_steps,
    iteration_stats,
    loadavg,
    machine_info,
    time_compiled,
)

import jaxmps
from jaxmps import PorousRegion

HERE = pathlib.Path(__file__).parent


def strips(count):
    """`count` vertical-damping boxes side by side under the surface of the
    0.5 m x 0.3 m tank."""
    width = 0.5 / count
    return [
        PorousRegion(((i * width, 0.15), ((i + 1) * width, 0.3)), 0.05)
        for i in range(count)
    ]


def taking_turns(first, second, n_steps, rounds=4):
    """(compile [s], run [s]) of each case's `n_steps` fixed steps: each compiled
    and timed as `_common.time_compiled` does, then called in turns `rounds`
    more times, the best of all its calls kept (on a shared host a program's
    best of three moved by up to 2x between calls; taking turns lets both see
    the same load)."""
    timed = []
    for case in (first, second):
        args = (case.scene, case.params, case.state, n_steps, n_steps, jaxmps.frame)
        timed.append((time_compiled(jaxmps.lower_simulate, *args, throw=False), args))
    best = [min(t.run_s_all) for t, _ in timed]
    for _ in range(rounds):
        for k, (t, args) in enumerate(timed):
            start = time.perf_counter()
            jax.block_until_ready(t.compiled(*args, throw=False))
            best[k] = min(best[k], time.perf_counter() - start)
    return [(t.trace_lower_s + t.compile_s, b) for (t, _), b in zip(timed, best)]


def main():
    seed_box = dict(porous_kappa=0.01, porous_box="-1,0.38,0.3,0.46")
    box_2d = dict(porous_kappa=0.05, porous_box="0.1,-1,0.3,1", porous_direction="all")
    box_3d = dict(porous_kappa=0.05, porous_box="-1,-1,0.1,2,2,0.3")
    # name: (scene, its settings, the baseline's extra settings, the measured extra)
    cases = {
        "sloped tank, seed's region": (
            jaxmps.scenes.sloshing_tank,
            dict(slope=1.5, spacing=0.01),
            {},
            seed_box,
        ),
        **{
            f"sloshing tank, {k} region(s)": (
                jaxmps.scenes.sloshing_tank,
                dict(spacing=0.01),
                {},
                dict(porous_regions=strips(k)),
            )
            for k in (1, 4, 16)
        },
        "3-D hydrostatic, 1 region": (
            jaxmps.scenes.hydrostatic,
            dict(dim=3, spacing=0.02),
            {},
            box_3d,
        ),
        "2-D hydrostatic, porosity 0.9 vs its region without": (
            jaxmps.scenes.hydrostatic,
            dict(width=0.4, depth=0.2, spacing=0.01),
            box_2d,
            dict(box_2d, porous_porosity=0.9),
        ),
        "3-D hydrostatic, porosity 0.85 vs its region without": (
            jaxmps.scenes.hydrostatic,
            dict(dim=3, spacing=0.02),
            box_3d,
            dict(box_3d, porous_porosity=0.85),
        ),
    }
    n_steps = 200
    rows = []
    for name, (build, settings, baseline, extra) in cases.items():
        plain = fixed_steps(build(**settings, **baseline))
        damped = fixed_steps(build(**settings, **extra))
        n = int(plain.state.active.sum())
        (c_with, r_with), (c_without, r_without) = taking_turns(damped, plain, n_steps)
        iterations = [
            float(np.mean(iteration_stats(c.scene, c.params, c.state, n_steps)[1]))
            for c in (damped, plain)
        ]
        rows.append(
            dict(
                case=name,
                particles=n,
                regions=damped.scene.porous.count,
                steps=n_steps,
                compile_with_s=c_with,
                compile_without_s=c_without,
                run_with_s=r_with,
                run_without_s=r_without,
                share_of_step=(r_with - r_without) / r_with,
                cg_iterations_with=iterations[0],
                cg_iterations_without=iterations[1],
                particle_steps_per_s=n * n_steps / r_with,
            )
        )
        print(rows[-1], flush=True)
    info = machine_info()
    info["loadavg_1min_end"] = loadavg()
    out = HERE / "results" / "porous_cost_cpu.json"
    out.write_text(json.dumps(dict(machine=info, rows=rows), indent=2))
    lines = [
        "# Porous damping regions: cost as a fraction of step time (CPU)",
        "",
        f"{info['cpu_model']}, {info['cpu_usable']} cores, jax {info['jax']}, "
        f"{info['dtype']}; {n_steps} fixed steps, run time best of 7 after a "
        "warm-up call, the last 4 taken in turns with the compared case.",
        "",
        "| case | particles | regions | compile with / without [s] | "
        "run with / without [s] | share of step | CG iterations per step "
        "with / without | particle-steps/s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['particles']} | {r['regions']} | "
            f"{r['compile_with_s']:.1f} / {r['compile_without_s']:.1f} | "
            f"{r['run_with_s']:.3f} / {r['run_without_s']:.3f} | "
            f"{100 * r['share_of_step']:.1f} % | "
            f"{r['cg_iterations_with']:.1f} / {r['cg_iterations_without']:.1f} | "
            f"{r['particle_steps_per_s']:.3g} |"
        )
    lines += [
        "",
        "With / without: the regions, or for the porosity rows the porosity "
        "(the baseline has the same region without one). A scene without regions "
        "compiles no region code (no `porous` stage in its program; "
        "tests/test_porous.py), one without a porosity no pore weights "
        "(tests/test_porosity.py). Shares within a few per cent of zero are "
        "load noise: compare the rows' spread.",
    ]
    (HERE / "results" / "porous_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
