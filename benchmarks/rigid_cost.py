"""Cost of the rigid-body component as a fraction of step time.

The same particles are run twice per scene: with the box as a rigid body, and with
the rigid component removed (the box's particles become fluid, so the step program
has no body code). Compile time and run time are reported separately; run times are
the best of three calls after an untimed one (`_common.time_compiled`).

A second table: the friction between bodies' Jacobi sweeps (`friction_sweeps`)
in scenes with blocks touching each other: a stack of three blocks (dry), two
blocks side by side in water, and the flume's groundsill with four rows of
blocks, each at 1 sweep and at 16 and 64 (the default).

Run: python benchmarks/rigid_cost.py  (writes results/rigid_cost_cpu.{json,md})
"""

import dataclasses
import json
import math
import pathlib

import equinox as eqx
import jax.numpy as jnp
from _common import compile_and_run, fixed_steps, loadavg, machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent


def without_bodies(case):
    """The case with its bodies turned into plain fluid (same particles)."""
    kind = jnp.where(case.state.kind == int(jaxmps.Kind.RIGID), 0, case.state.kind)
    return (
        dataclasses.replace(case.scene, rigid=None),
        dataclasses.replace(case.params, rigid=None),
        dataclasses.replace(case.state, kind=kind, rigid=None),
    )


def touching_blocks() -> dict:
    """Scenes whose blocks touch each other (fixed steps)."""
    sill = dict(
        spacing=0.0025,
        discharge=0.006,
        inflow_depth=0.015,
        crest_length=0.05,
        step_height=0.01,
        apron_length=0.1,
        reach_length=0.4,
        block_rows=4,
        block_length=0.0175,
        block_height=0.0125,
        block_gap=0.0,
        scour_length=0.2,
        scour_depth=0.05,
        scour_exposure=0.01,
        transition_length=0.2,
        bed_lowering=0.02,
        bed_length=0.9,
    )
    tilt = math.degrees(math.atan(0.5))
    return {
        "block_stack, three (dry)": jaxmps.scenes.block_stack(
            blocks=3, base_width=2.0, block_height=0.25, dt=0.001, settle=0.0
        ),
        "block_stack, row in water": jaxmps.scenes.block_stack(
            layout="row", angle=tilt, water_depth=1.0, settle=0.0
        ),
        "flume, 4 rows of blocks": jaxmps.scenes.flume(**sill),
    }


def sweep_rows(n_steps: int) -> list[dict]:
    rows = []
    for name, case in touching_blocks().items():
        case = fixed_steps(case)
        for sweeps in (1, 16, 64):
            scene = eqx.tree_at(lambda s: s.rigid.friction_sweeps, case.scene, sweeps)
            c, r = compile_and_run(scene, case.params, case.state, n_steps)
            rows.append(
                dict(
                    scene=name,
                    particles=int(case.state.active.sum()),
                    body_particles=int((case.state.rigid.body >= 0).sum()),
                    bodies=case.scene.rigid.count,
                    sweeps=sweeps,
                    steps=n_steps,
                    compile_s=c,
                    run_s=r,
                )
            )
            print(rows[-1])
    return rows


def main():
    rows = []
    cases = {
        "floating_box": fixed_steps(jaxmps.scenes.floating_box()),
        "block_impact": fixed_steps(jaxmps.scenes.block_impact()),
        "friction_tilt": fixed_steps(jaxmps.scenes.friction_tilt(settle=0.0)),
    }
    n_steps = 200
    for name, case in cases.items():
        n = int(case.state.active.sum())
        c_body, r_body = compile_and_run(case.scene, case.params, case.state, n_steps)
        c_free, r_free = compile_and_run(*without_bodies(case), n_steps)
        rows.append(
            dict(
                scene=name,
                particles=n,
                body_particles=int((case.state.rigid.body >= 0).sum()),
                steps=n_steps,
                compile_with_bodies_s=c_body,
                compile_without_s=c_free,
                run_with_bodies_s=r_body,
                run_without_s=r_free,
                rigid_fraction_of_step=(r_body - r_free) / r_body,
                particle_steps_per_s=n * n_steps / r_body,
            )
        )
        print(rows[-1])
    sweeps = sweep_rows(n_steps)
    info = machine_info()
    info["loadavg_1min_end"] = loadavg()
    out = HERE / "results" / "rigid_cost_cpu.json"
    out.write_text(json.dumps(dict(machine=info, rows=rows, sweeps=sweeps), indent=2))
    lines = [
        "# Rigid-body component: cost as a fraction of step time (CPU)",
        "",
        f"{info['cpu_model']}, {info['cpu_usable']} cores, jax {info['jax']}, "
        f"{info['dtype']}; {n_steps} steps, run time best of 3 after a warm-up call.",
        "",
        "| scene | particles | body particles | compile with / without [s] | "
        "run with / without [s] | rigid share of step | particle-steps/s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['particles']} | {r['body_particles']} | "
            f"{r['compile_with_bodies_s']:.1f} / {r['compile_without_s']:.1f} | "
            f"{r['run_with_bodies_s']:.3f} / {r['run_without_s']:.3f} | "
            f"{100 * r['rigid_fraction_of_step']:.1f} % | "
            f"{r['particle_steps_per_s']:.3g} |"
        )
    lines += [
        "",
        "A scene without bodies compiles no body code at all (no `rigid` stage in "
        "its program; see tests/test_pipeline.py, "
        "test_scene_without_bodies_compiles_no_body_code).",
        "",
        "## Friction between bodies: the cost of its sweeps",
        "",
        "The same program with `friction_sweeps` 1, 16 and 64 (the default); "
        f"{n_steps} fixed steps, best of 3.",
        "",
        "| scene | particles | body particles | bodies | sweeps | compile [s] | "
        "run [s] | vs 1 sweep |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in sweeps:
        one = next(
            q["run_s"] for q in sweeps if q["scene"] == r["scene"] and q["sweeps"] == 1
        )
        lines.append(
            f"| {r['scene']} | {r['particles']} | {r['body_particles']} | "
            f"{r['bodies']} | {r['sweeps']} | {r['compile_s']:.1f} | "
            f"{r['run_s']:.3f} | {r['run_s'] / one:.3f} |"
        )
    (HERE / "results" / "rigid_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
