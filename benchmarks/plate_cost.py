"""Cost of submerged plates (seed 001 §4) as a fraction of step time.

Urata's tank (0.45 m x 0.25 m of water, shaken with A = 2 mm at 1.2769 Hz from
the first step) without plates and with plates 100 mm and 25 mm down at both
walls (0.1 m long), at l0 = 1 cm and 5 mm, standard scheme. A plate is particles
(its walls are unknowns of the pressure solve, its dummies are not) in the
water's place: the particle count hardly changes, so what a plate costs is what
it does to the pressure solve and the neighbour lists. Compile time and run time
are reported separately; run times are the best of three calls after an untimed
one (`_common.time_compiled`), fixed steps.

Run: python benchmarks/plate_cost.py  (writes results/plate_cost_cpu.{json,md})
"""

import json
import pathlib

from _common import compile_and_run, fixed_steps, loadavg, machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
URATA = dict(tank_length=0.45, depth=0.25, tank_height=0.45, settle=0.0)


def main():
    n_steps = 1000
    rows = []
    for spacing in (0.01, 0.005):
        for plate in (None, 0.1, 0.025):
            extra = {} if plate is None else dict(plate_depth=plate)
            case = fixed_steps(
                jaxmps.scenes.sloshing_tank(
                    spacing=spacing, frequency=1.276909, **URATA, **extra
                )
            )
            compile_s, run_s = compile_and_run(
                case.scene, case.params, case.state, n_steps
            )
            n = int(case.state.active.sum())
            rows.append(
                dict(
                    spacing=spacing,
                    plate=plate,
                    particles=n,
                    fluid=int((case.state.kind == 0).sum()),
                    steps=n_steps,
                    compile_s=compile_s,
                    run_s=run_s,
                    particle_steps_per_s=n * n_steps / run_s,
                )
            )
            print(rows[-1], flush=True)
    for r in rows:
        bare = next(b for b in rows if b["spacing"] == r["spacing"] and not b["plate"])
        r["run_over_bare"] = r["run_s"] / bare["run_s"]
    info = machine_info()
    info["loadavg_1min_end"] = loadavg()
    out = HERE / "results" / "plate_cost_cpu.json"
    out.write_text(json.dumps(dict(machine=info, rows=rows), indent=2))
    lines = [
        "# Submerged plates: cost against the bare tank (CPU)",
        "",
        f"{info['cpu_model']}, {info['cpu_usable']} cores, jax {info['jax']}, "
        f"{info['dtype']}; Urata's tank shaken at 1.2769 Hz, standard scheme, "
        f"{n_steps} fixed steps, run time best of 3 after a warm-up call.",
        "",
        "| l0 [mm] | plates | particles (fluid) | compile [s] | run [s] "
        "| run / bare tank | particle-steps/s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        plates = "none" if r["plate"] is None else f"{r['plate'] * 1e3:g} mm down"
        lines.append(
            f"| {r['spacing'] * 1e3:g} | {plates} | {r['particles']} ({r['fluid']}) "
            f"| {r['compile_s']:.1f} | {r['run_s']:.3f} | {r['run_over_bare']:.3f} "
            f"| {r['particle_steps_per_s']:.3g} |"
        )
    lines += [
        "",
        "Plates change the particles' places and kinds, not the arrays' shapes: a "
        "tank of the same particle count runs the program already compiled (a "
        "compile time near zero is that cache).",
    ]
    (HERE / "results" / "plate_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
