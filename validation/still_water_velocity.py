"""Still water that should stay still: the particles' speeds in a tank at rest.

`scenes.hydrostatic` (semi-implicit, adaptive steps, float64) is released from
its lattice and run for `--duration` seconds; at ten save times the largest
fluid speed, and at the end the r.m.s. speed of the top layer (the particles
within l0 of the still surface) and of the water below it, each against the
shallow-water wave speed sqrt(g H) for scale. Per scheme: the default
(`standard`: minimum-pressure shift and collision guard) and `standard_ds`
(dynamic stabilisation instead of both).

Run: python validation/still_water_velocity.py [--tanks 0.02:1.0:0.4 ...]
     [--schemes standard standard_ds] [--duration 4]
(about 5 min on 2 cores; writes results/still_water_velocity_cpu.{json,md})
"""

import argparse
import json
import math
import time

import jax
import numpy as np
from _common import HERE, machine_info

import jaxmps


def measure(spacing: float, width: float, depth: float, scheme: str, duration: float):
    case = jaxmps.scenes.hydrostatic(
        spacing=spacing, width=width, depth=depth, scheme=scheme
    )
    fluid = np.asarray(case.state.kind) == int(jaxmps.Kind.FLUID)
    times = np.linspace(duration / 10, duration, 10)
    start = time.perf_counter()
    tr = jaxmps.simulate(
        case.scene, case.params, case.state, times=times, observe=jaxmps.frame
    )
    wall = time.perf_counter() - start
    speed = np.linalg.norm(np.asarray(tr.saved.velocity)[:, fluid], axis=-1)
    height = np.asarray(tr.saved.position)[-1][fluid, -1]
    top = height > depth - spacing
    return dict(
        spacing=spacing,
        width=width,
        depth=depth,
        scheme=scheme,
        duration=duration,
        result=jaxmps._result.result_name(tr.result),
        wave_speed=math.sqrt(9.81 * depth),
        times=times.tolist(),
        max_speed=speed.max(axis=1).tolist(),
        rms_top=float(np.sqrt(np.mean(speed[-1][top] ** 2))),
        rms_below=float(np.sqrt(np.mean(speed[-1][~top] ** 2))),
        over_5cm=int(np.sum(speed[-1] > 0.05)),
        particles=int(fluid.sum()),
        steps=int(np.sum(tr.steps.accepted)),
        wall_s=wall,
    )


def table(rows) -> str:
    lines = [
        "| l0 [m] | tank W x H [m] | scheme | largest speed at t/10, ..., t [m/s] "
        "| r.m.s. top layer / below at t [m/s] | over 5 cm/s at t | sqrt(g H) "
        "[m/s] | t [s] | steps | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        speeds = " ".join(f"{v:.3f}" for v in r["max_speed"])
        lines.append(
            f"| {r['spacing']} | {r['width']} x {r['depth']} | {r['scheme']} "
            f"| {speeds} | {r['rms_top']:.4f} / {r['rms_below']:.4f} "
            f"| {r['over_5cm']} of {r['particles']} | {r['wave_speed']:.2f} "
            f"| {r['duration']:g} | {r['steps']} | {r['wall_s']:.0f} |"
        )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tanks",
        nargs="+",
        default=["0.02:1.0:0.4", "0.01:0.5:0.2"],
        help="spacing:width:depth",
    )
    parser.add_argument("--schemes", nargs="+", default=["standard", "standard_ds"])
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        help="seconds (default: 10 sqrt(H / g) x 2)",
    )
    parser.add_argument("--out", default="still_water_velocity_cpu")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    rows = []
    for tank in args.tanks:
        spacing, width, depth = (float(v) for v in tank.split(":"))
        duration = args.duration or round(20 * math.sqrt(depth / 9.81), 1)
        for scheme in args.schemes:
            row = measure(spacing, width, depth, scheme, duration)
            print(json.dumps(row), flush=True)
            rows.append(row)
    info = machine_info()
    path = HERE / "results" / args.out
    path.with_suffix(".json").write_text(
        json.dumps({"machine": info, "rows": rows}, indent=1)
    )
    path.with_suffix(".md").write_text(
        "# Still water: the particles' speeds in a tank at rest\n\n"
        f"Machine: {info['cpu_model']}, {info['cpu_count']} cores; float64; "
        "`validation/still_water_velocity.py` (semi-implicit, adaptive steps). "
        "Top layer: the fluid particles within l0 of the still surface at the "
        "end.\n\n" + table(rows) + "\n"
    )


if __name__ == "__main__":
    main()
