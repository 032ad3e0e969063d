"""Cost of the rigid-body component as a fraction of step time.

The same particles are run twice per scene: with the box as a rigid body, and with
the rigid component removed (the box's particles become fluid, so the step program
has no body code). Compile time and run time are reported separately; run times are
the best of three calls after an untimed one (`_common.time_compiled`).

Run: python benchmarks/rigid_cost.py  (writes results/rigid_cost_cpu.{json,md})
"""

import dataclasses
import json
import pathlib

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
    info = machine_info()
    info["loadavg_1min_end"] = loadavg()
    out = HERE / "results" / "rigid_cost_cpu.json"
    out.write_text(json.dumps(dict(machine=info, rows=rows), indent=2))
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
    ]
    (HERE / "results" / "rigid_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
