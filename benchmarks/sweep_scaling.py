"""Members per second of `jaxmps.sweep` against the member count and the device
count.

The 2-D dam break (spacing 0.0146 m, 518 particles, 160 fixed steps of the scene's
largest step, probes every 20) swept over 1, 2, 4, 8 and 16 viscosities, on 1, 2
and 4 devices. Each device count runs in a process of its own (CPU devices are
forced with XLA_FLAGS=--xla_force_host_platform_device_count=N before JAX
starts; on a GPU machine, the GPUs that exist). Per row: the first call
(compilation included) and the best of three further calls (run time), members per
second and particle-steps per second. Forced CPU devices share the machine's cores:
they show what splitting costs, not what more hardware buys.

Usage:
    python benchmarks/sweep_scaling.py                 # CPU, 1/2/4 forced devices
    python benchmarks/sweep_scaling.py --devices 1 2   # (GPU: the GPUs there are)

Writes `benchmarks/results/sweep_scaling_<backend>.{json,md}`.
"""

import argparse
import json
from pathlib import Path

from _common import rows_per_device_count, write_rows

HERE = Path(__file__).resolve().parent
MEMBERS = (1, 2, 4, 8, 16)


def measure(devices: int, members: tuple[int, ...]) -> list[dict]:
    """Rows for one device count (run inside the process that has them)."""
    import time

    import jax
    import numpy as np
    from _common import fixed_steps

    import jaxmps

    case = fixed_steps(jaxmps.scenes.dam_break(spacing=0.0146))
    mesh = jaxmps.member_mesh(devices=devices)
    n_steps, save = 160, 20
    rows = []
    for b in members:
        values = {"viscosity": np.geomspace(1e-6, 1e-4, b)}
        t0 = time.perf_counter()
        first = jaxmps.sweep(case, values, n_steps, save, mesh=mesh)
        first_s = time.perf_counter() - t0
        runs = [
            jaxmps.sweep(case, values, n_steps, save, mesh=mesh).wall_time
            for _ in range(3)
        ]
        run_s = min(runs)
        rows.append(
            dict(
                devices=devices,
                members=b,
                first_call_s=first_s,
                run_s=run_s,
                members_per_s=b / run_s,
                particle_steps_per_s=b * case.scene.capacity * n_steps / run_s,
                failed=len(first.failed()),
                backend=jax.default_backend(),
                capacity=int(case.scene.capacity),
            )
        )
        print(json.dumps(rows[-1]), flush=True)
    return rows


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--devices", type=int, nargs="+", default=[1, 2, 4])
    p.add_argument("--members", type=int, nargs="+", default=list(MEMBERS))
    p.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    if args.child is not None:
        measure(args.child, tuple(args.members))
        return
    rows = rows_per_device_count(
        __file__, args.devices, ["--members", *map(str, args.members)]
    )
    write_rows("sweep_scaling", args.out, rows, _markdown)


def _markdown(info: dict, rows: list[dict]) -> str:
    single = {r["members"]: r["run_s"] for r in rows if r["devices"] == 1}
    lines = [
        "# Sweep scaling: members per second against members and devices",
        "",
        f"Machine: {info['cpu_model']}, {info['cpu_usable']} cores usable, backend "
        f"{info['backend']}; {info['dtype']}. Script: `benchmarks/sweep_scaling.py`. "
        "2-D dam break, 518 particles, 160 fixed steps per member.",
        "",
        "| devices | members | first call [s] | run [s] | members/s | "
        "particle-steps/s | run / one device |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ratio = r["run_s"] / single[r["members"]] if r["members"] in single else None
        lines.append(
            f"| {r['devices']} | {r['members']} | {r['first_call_s']:.2f} | "
            f"{r['run_s']:.3f} | {r['members_per_s']:.2f} | "
            f"{r['particle_steps_per_s']:.3g} | "
            + (f"{ratio:.2f}" if ratio is not None else "")
            + " |"
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
