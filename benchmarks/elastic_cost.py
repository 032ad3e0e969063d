"""Cost of the elastic-body component: its share of step time and compile time,
and how it scales with the particles.

Each case runs twice: as built, and with the elastic component removed (its free
particles become fluid, its clamped ones stay walls), so that the second step
program has no elastic code. Compile time (trace + lower + compile) and run time
(best of three calls after an untimed one) are reported apart. The elastic stage
runs `substeps` sub-steps per step; its cost per particle and sub-step is
(run with - run without) / (steps x sub-steps x elastic particles).

Cases: `elastic_plate` (water on a plate: the coupled case), `block_impact`
with an elastic block (one sub-step per step), and `elastic_cantilever` at 4, 8
and 16 particles through the thickness (no fluid: the elastic stage is most of
the step).

Run: python benchmarks/elastic_cost.py  (writes results/elastic_cost_cpu.{json,md})
"""

import dataclasses
import json
import pathlib

import jax
import jax.numpy as jnp
from _common import compile_and_run, fixed_steps, loadavg, machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent


def without_elastic(case):
    """The case with its elastic component removed (same particles)."""
    kind = jnp.where(case.state.kind == int(jaxmps.Kind.ELASTIC), 0, case.state.kind)
    return (
        dataclasses.replace(case.scene, elastic=None),
        dataclasses.replace(case.params, elastic=None),
        dataclasses.replace(case.state, kind=kind, elastic=None),
    )


def main():
    jax.config.update("jax_enable_x64", True)
    cases = {
        "elastic_plate": (jaxmps.scenes.elastic_plate(), 100),
        "block_impact (elastic)": (
            jaxmps.scenes.block_impact(body="elastic", dt=1e-3, substeps=1),
            200,
        ),
    }
    for layers in (4, 8, 16):
        case = jaxmps.scenes.elastic_cantilever(spacing=0.02 / layers)
        cases[f"elastic_cantilever, {layers} layers"] = (case, 50)
    rows = []
    for name, (case, n_steps) in cases.items():
        case = fixed_steps(case)
        n = int(case.state.active.sum())
        m = int(case.state.elastic.index.shape[0])
        substeps = case.scene.elastic.substeps
        c_with, r_with = compile_and_run(case.scene, case.params, case.state, n_steps)
        c_without, r_without = compile_and_run(*without_elastic(case), n_steps)
        rows.append(
            dict(
                case=name,
                particles=n,
                elastic_particles=m,
                substeps=substeps,
                steps=n_steps,
                compile_with_s=c_with,
                compile_without_s=c_without,
                run_with_s=r_with,
                run_without_s=r_without,
                elastic_share=(r_with - r_without) / r_with,
                ns_per_particle_substep=1e9
                * (r_with - r_without)
                / (n_steps * substeps * m),
                particle_steps_per_s=n * n_steps / r_with,
            )
        )
        print(rows[-1], flush=True)
    info = machine_info()
    info["loadavg_1min_end"] = loadavg()
    out = HERE / "results" / "elastic_cost_cpu.json"
    out.write_text(json.dumps(dict(machine=info, rows=rows), indent=2))
    lines = [
        "# Elastic-body component: share of step and compile time (CPU, float64)",
        "",
        "Best of 3 runs after an untimed one; 'without': the elastic component",
        "removed (its particles fluid). Per particle-sub-step: the difference over",
        "steps x sub-steps x elastic particles.",
        "",
        "| case | particles | elastic | sub-steps | steps | compile with / without "
        "[s] | run with / without [s] | elastic share | ns per particle-sub-step "
        "| particle-steps/s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['particles']} | {r['elastic_particles']} "
            f"| {r['substeps']} | {r['steps']} "
            f"| {r['compile_with_s']:.1f} / {r['compile_without_s']:.1f} "
            f"| {r['run_with_s']:.3f} / {r['run_without_s']:.3f} "
            f"| {100 * r['elastic_share']:.0f} % "
            f"| {r['ns_per_particle_substep']:.0f} "
            f"| {r['particle_steps_per_s']:.3g} |"
        )
    lines += ["", f"Machine: {info}"]
    (HERE / "results" / "elastic_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
