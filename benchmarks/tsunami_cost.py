"""Cost of the tsunami-over-a-quay scenario (`scenes.tsunami_quay`) in 2-D and
3-D: compile time and run time separately, particle-steps/s counted over the
slots the step computes (the capacity: active particles and the inflow's pool) and
over the particles active at the start, peak memory, and what seed 000's 3-D
runs (about 1.1 M particles, 180 s at dt = 0.01 s: 18,000 steps) would cost at
the measured 3-D rate.

Each configuration runs `--steps` fixed steps (the scene's largest step) from
its initial state, best of three calls after an untimed one. `--whole` also runs
one reduced 3-D scenario (a 40 m ship in a 60 m channel, l0 = 2 m) through its
whole wave with adaptive steps and reports its wall time.

Run: python benchmarks/tsunami_cost.py [--steps 100] [--whole] [--configs LABEL ...]
(writes results/tsunami_cost_<backend>.{json,md}).
"""

import argparse
import resource
import time

import jax
import numpy as np
from _common import compile_and_run, fixed_steps, loadavg, write_rows

import jaxmps

SEED_PARTICLES = 1.1e6
SEED_STEPS = 18_000  # 180 s at dt = 0.01 s (seed 000 Table 4.1-2)

REDUCED_3D = dict(
    dim=3,
    sea_length=40.0,
    quay_length=60.0,
    ship_length=40.0,
    width=60.0,
    gauges=2,
    gauge_spacing=6.0,
    offshore_gauge=20.0,
)

CONFIGS = {
    "2-D, l0 = 1 m": dict(spacing=1.0),
    "2-D, l0 = 0.5 m": dict(spacing=0.5),
    "3-D reduced, l0 = 2 m": dict(REDUCED_3D, spacing=2.0),
    "3-D reduced, l0 = 1.5 m": dict(REDUCED_3D, spacing=1.5),
    # The scene's own geometry (a 100 m ship in a 134 m channel, a 40 m wave)
    # at seed 000's l0 = 1 m: about 0.77 M slots (0.21 M active at the start)
    # against the seed's 1.1 M particles. For a GPU.
    "3-D, l0 = 1 m (seed's resolution)": dict(dim=3, spacing=1.0),
}


def peak_memory_mib() -> float:
    """This process's peak resident memory so far [MiB] (host: CPU runs)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure(label: str, settings: dict, steps: int) -> dict:
    case = fixed_steps(jaxmps.scenes.tsunami_quay(**settings))
    compile_s, run_s = compile_and_run(case.scene, case.params, case.state, steps)
    capacity = case.scene.capacity
    active = int(case.state.active.sum())
    rate = capacity * steps / run_s
    return dict(
        label=label,
        dim=case.scene.dim,
        spacing=settings["spacing"],
        capacity=capacity,
        active_at_start=active,
        steps=steps,
        compile_s=round(compile_s, 2),
        run_s=round(run_s, 3),
        slot_steps_per_s=rate,
        active_steps_per_s=active * steps / run_s,
        dt=float(case.params.dt),
        peak_memory_mib=round(peak_memory_mib(), 1),
        seed_run_hours=SEED_PARTICLES * SEED_STEPS / rate / 3600,
        load=loadavg(),
    )


def whole_run(settings: dict) -> dict:
    """The reduced 3-D scenario through its whole wave, adaptive steps."""
    case = jaxmps.scenes.tsunami_quay(**settings)
    observe = jaxmps.scenes.observe_probes(case.probes)
    start = time.perf_counter()
    run = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=[case.t_end],
        observe=observe,
        throw=False,
    )
    jax.block_until_ready(run.state.position)
    saved = {k: np.asarray(v) for k, v in run.saved.items()}
    return dict(
        label="3-D reduced, whole wave",
        settings=settings,
        result=jaxmps._result.result_name(run.result),
        simulated_s=float(run.state.time),
        steps=int(run.state.step),
        capacity=case.scene.capacity,
        wall_s=round(time.perf_counter() - start, 1),
        ship_x_end=float(saved["ship_x"][-1]),
        quay_edge=case.config["quay_edge"],
        load=loadavg(),
    )


def markdown(info: dict, rows: list[dict]) -> str:
    lines = [
        "# Tsunami over a quay: cost",
        "",
        f"Machine: {info}",
        "",
        "| case | slots | active at start | compile [s] | run [s] / steps |"
        " slot-steps/s | seed run (1.1 M x 18,000 steps) [h] | peak memory [MiB] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "slot_steps_per_s" not in r:
            continue
        lines.append(
            f"| {r['label']} | {r['capacity']} | {r['active_at_start']} | "
            f"{r['compile_s']} | {r['run_s']} / {r['steps']} | "
            f"{r['slot_steps_per_s']:.3g} | {r['seed_run_hours']:.0f} | "
            f"{r['peak_memory_mib']} |"
        )
    for r in rows:
        if r["label"] == "3-D reduced, whole wave":
            lines += [
                "",
                f"Whole wave, 3-D reduced ({r['settings']}): {r['simulated_s']:.1f} s "
                f"simulated in {r['steps']} steps, {r['wall_s']:.0f} s wall "
                f"({r['result']}); ship centre at x = {r['ship_x_end']:.1f} m, quay "
                f"edge at {r['quay_edge']:.1f} m.",
            ]
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--whole", action="store_true")
    # By default all but the seed-resolution case (a GPU's: `gpu_suite.sh`).
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS)[:4])
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    rows = []
    for label in args.configs:
        rows.append(measure(label, CONFIGS[label], args.steps))
        print(rows[-1], flush=True)
    if args.whole:
        rows.append(whole_run(dict(REDUCED_3D, spacing=2.0, t_end=25.0)))
        print(rows[-1], flush=True)
    write_rows("tsunami_cost", args.out, rows, markdown)


if __name__ == "__main__":
    main()
