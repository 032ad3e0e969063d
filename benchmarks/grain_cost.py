"""Cost of the DEM grains: their share of step time and compile time, contacts
per grain, and how a step scales with the grain count.

Each case runs twice: as built, and with the grain component removed (the
grains become plain particles of the fluid: in a dry scene nothing moves them),
so that the second step program has no grain code. Compile time (trace + lower
+ compile) and run time (best of three calls after an untimed one, fixed steps)
are reported apart. The grains take `substeps` DEM sub-steps per step; their
cost per grain and sub-step is (run with - run without) / (steps x sub-steps x
grains).

Cases: `grain_settling` (one grain in a water tank: what a grain in water costs
the step), and dry `granular_collapse` columns of 50 to 3200 grains (the DEM is
most of the step there).

Run: python benchmarks/grain_cost.py  (writes results/grain_cost_cpu.{json,md})
"""

import dataclasses
import json
import pathlib

import jax
import jax.numpy as jnp
from _common import compile_and_run, fixed_steps, loadavg, machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent


def without_grains(case):
    """The case with its grain component removed (same particles)."""
    kind = jnp.where(case.state.kind == int(jaxmps.Kind.SEDIMENT), 0, case.state.kind)
    return (
        dataclasses.replace(case.scene, grains=None),
        dataclasses.replace(case.params, grains=None),
        dataclasses.replace(case.state, kind=kind, grains=None),
    )


def main():
    jax.config.update("jax_enable_x64", True)
    cases = {"grain_settling": (jaxmps.scenes.grain_settling(), 100)}
    for width, height in ((0.025, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 0.4)):
        case = jaxmps.scenes.granular_collapse(
            column_width=width,
            column_height=height,
            floor_length=4 * width,
            spacing=0.005,
        )
        cases[f"granular_collapse {width:g} x {height:g} m"] = (case, 50)
    rows = []
    for name, (case, n_steps) in cases.items():
        if case.scene.grains.count > 1:
            # From the heap 0.3 s into its collapse (its grains in contact), not
            # from the column, whose grains start apart and fall together.
            later = jaxmps.simulate(case.scene, case.params, case.state, times=[0.3])
            case = dataclasses.replace(case, state=later.state)
        case = fixed_steps(case)
        n = int(case.state.active.sum())
        m = int(case.scene.grains.count)
        substeps = case.scene.grains.substeps
        c_with, r_with = compile_and_run(case.scene, case.params, case.state, n_steps)
        c_without, r_without = compile_and_run(*without_grains(case), n_steps)
        out = jaxmps.simulate(case.scene, case.params, case.state, n_steps, n_steps)
        contacts = float(jnp.mean(out.state.grains.contact_count))
        rows.append(
            dict(
                case=name,
                particles=n,
                grains=m,
                substeps=substeps,
                steps=n_steps,
                contacts_per_grain=contacts,
                compile_with_s=c_with,
                compile_without_s=c_without,
                run_with_s=r_with,
                run_without_s=r_without,
                grain_share=(r_with - r_without) / r_with,
                ns_per_grain_substep=1e9
                * (r_with - r_without)
                / (n_steps * substeps * m),
                particle_steps_per_s=n * n_steps / r_with,
            )
        )
        print(rows[-1], flush=True)
    info = machine_info()
    info["loadavg_1min_end"] = loadavg()
    out = HERE / "results" / "grain_cost_cpu.json"
    out.write_text(json.dumps(dict(machine=info, rows=rows), indent=2))
    lines = [
        "# DEM grains: share of step and compile time (CPU, float64)",
        "",
        "Best of 3 runs after an untimed one, fixed steps; 'without': the grain",
        "component removed (its particles plain). Per grain-sub-step: the",
        "difference over steps x sub-steps x grains. The columns are timed from",
        "0.3 s into their collapse; contacts per grain: the mean at the end.",
        "",
        "| case | particles | grains | sub-steps | steps | contacts per grain | "
        "compile with / without [s] | run with / without [s] | grain share | "
        "ns per grain-sub-step | particle-steps/s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['particles']} | {r['grains']} | {r['substeps']} "
            f"| {r['steps']} | {r['contacts_per_grain']:.2f} "
            f"| {r['compile_with_s']:.1f} / {r['compile_without_s']:.1f} "
            f"| {r['run_with_s']:.3f} / {r['run_without_s']:.3f} "
            f"| {100 * r['grain_share']:.0f} % "
            f"| {r['ns_per_grain_substep']:.0f} "
            f"| {r['particle_steps_per_s']:.3g} |"
        )
    lines += ["", f"Machine: {info}"]
    (HERE / "results" / "grain_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
