"""Cost of each high-accuracy correction (seed 001 ablation ladder) as a fraction of
step time, and the accuracy each rung gives in the hydrostatic tank.

The same hydrostatic tank (0.2 m x 0.2 m, l0 = 1 cm, r_e = 2.4 l0, 1 s) is run with
seed 001's standard MPS (`jaxmps.schemes.standard_mps`, the baseline the seed
measures against) and each rung of `jaxmps.schemes.LADDER`: standard -> HS ->
HS-HL -> HS-HL-ECS -> HS-HL-ECS-GC-DS -> high_accuracy (+ Wendland), with the
lattice-normalised HS/HL pair, and the standard rung with the seed's zero-gradient
wall dummies instead of the hydrostatic ones (`SemiImplicit.dummy_head`). Compile
time and run time are separate; the run time is the best of three calls after an
untimed one (`_common.time_compiled`). Reported per rung: ms/step, the
step time relative to the standard rung, and the bottom-pressure error and noise
(mean and standard deviation over t >= 0.5 s of the `pressure_bottom` probe,
relative to rho g (H - l0/2), the weight of the water above the probe).

Run: python benchmarks/scheme_cost.py  (writes results/scheme_cost_cpu.{json,md})
"""

import json
import pathlib

import equinox as eqx
import numpy as np
from _common import fixed_steps, loadavg, machine_info, time_compiled

import jaxmps

HERE = pathlib.Path(__file__).parent
RHO_G = 1000.0 * 9.81


class Observe(eqx.Module):
    probe: object

    def __call__(self, scene, state):
        return {"time": state.time, "p": self.probe(scene, state)}


def rung_scene(case, discretisation):
    g = case.scene.grid
    lower = np.asarray(g.origin)
    upper = lower + np.asarray(g.shape) * g.cell_size - 1e-9
    m = int(case.state.active.sum())
    return jaxmps.make_scene(
        np.asarray(case.state.position)[:m],
        case.scene.spacing,
        (lower, upper),
        scheme=discretisation,
    )


def measure(scene, params, state, n_steps, save_every, observe):
    """(compile [s], best of 3 runs [s], trajectory)."""
    timed = time_compiled(
        jaxmps.lower_simulate,
        scene,
        params,
        state,
        n_steps,
        save_every,
        observe,
        throw=False,
    )
    return timed.trace_lower_s + timed.compile_s, timed.run_s_best, timed.output


def main():
    case = fixed_steps(
        jaxmps.scenes.hydrostatic(
            spacing=0.01, width=0.2, depth=0.2, scheme="high_accuracy"
        )
    )
    params, state = case.params, case.state
    dt = float(params.dt)
    save_every = 10
    n_steps = int(1.0 / dt) // save_every * save_every
    observe = Observe(next(p for p in case.probes if p.name == "pressure_bottom"))
    # the weight of the water above the probe's nominal height l0/2
    reference = RHO_G * (float(case.config["depth"]) - 0.5 * case.scene.spacing)
    # Seed 001's baseline first, then the ladder from our default scheme.
    rungs = {"standard MPS (seed 001 §2)": jaxmps.schemes.standard_mps()}
    for name, toggles in jaxmps.schemes.LADDER.items():
        rungs[name] = jaxmps.schemes.high_accuracy(**toggles)
        if name == "standard":
            rungs["standard, zero-gradient walls"] = rungs[name].replace(
                solver=jaxmps.SemiImplicit(dummy_head=False)
            )
    rungs["high_accuracy (normalised HS/HL)"] = jaxmps.schemes.high_accuracy(
        normalised=True
    )
    rows = []
    for name, discretisation in rungs.items():
        scene = rung_scene(case, discretisation)
        compile_s, run_s, tr = measure(
            scene, params, state, n_steps, save_every, observe
        )
        t = np.asarray(tr.saved["time"])
        p = np.asarray(tr.saved["p"])[t >= 0.5]
        rows.append(
            dict(
                rung=name,
                steps=n_steps,
                particles=int(state.active.sum()),
                compile_s=compile_s,
                run_s=run_s,
                ms_per_step=1e3 * run_s / n_steps,
                result=0 if bool(tr.result == jaxmps.Result.successful) else 1,
                p_bottom_error=float(p.mean() / reference - 1),
                p_bottom_noise=float(p.std() / reference),
            )
        )
        print(rows[-1], flush=True)
    base = next(r["run_s"] for r in rows if r["rung"] == "standard")
    for r in rows:
        r["step_time_vs_standard"] = r["run_s"] / base
    out = dict(machine=machine_info(), loadavg_1min_end=loadavg(), rows=rows)
    (HERE / "results" / "scheme_cost_cpu.json").write_text(json.dumps(out, indent=2))
    lines = [
        "# Cost and hydrostatic accuracy of each high-accuracy correction (CPU)",
        "",
        f"Hydrostatic tank 0.2 m x 0.2 m, l0 = 1 cm, r_e = 2.4 l0, "
        f"{rows[0]['particles']} particles, dt = {1e3 * dt:.3f} ms, "
        f"{n_steps} steps (1 s). Pressure error / noise: mean / std over t >= 0.5 s "
        "of the bottom probe relative to rho g (H - l0/2).",
        "",
        "| rung | ms/step | step time vs standard | compile [s] "
        "| P_bottom error | P_bottom noise (std) | result |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['rung']} | {r['ms_per_step']:.2f} "
            f"| {r['step_time_vs_standard']:.2f} | {r['compile_s']:.1f} "
            f"| {100 * r['p_bottom_error']:+.1f} % | {100 * r['p_bottom_noise']:.1f} % "
            f"| {'ok' if r['result'] == 0 else r['result']} |"
        )
    lines += ["", f"1-min load average at the end: {out['loadavg_1min_end']}"]
    (HERE / "results" / "scheme_cost_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
