"""One run split over devices: time per step and collective volume against the
device count.

The 2-D dam break (about 2,900 particles by default; a spacing whose capacity the
device counts divide), fixed steps of the scene's largest step. Its state is split
over 1, 2 and 4 devices along the particle axis (`jaxmps.shard_particles`: blocks
of consecutive particles, which the scenes lay out row by row, so a block is a
band of the tank) and `simulate` runs one program that XLA partitions (GSPMD).
Per device count, in a process of its own (CPU devices forced with XLA_FLAGS):
compile time, run time per step (best of 3), the largest difference of the
positions from the one-device run, and the collectives in the compiled program
(count and bytes by kind, from the optimised HLO; those inside the step's loop
body run once per step).

Usage:
    python benchmarks/sharded_run.py                  # CPU, 1/2/4 forced devices
    python benchmarks/sharded_run.py --particles 12000

Writes `benchmarks/results/sharded_run_<backend>.{json,md}`.
"""

import argparse
import json
import math
import re
from pathlib import Path

from _common import rows_per_device_count, write_rows

HERE = Path(__file__).resolve().parent
_BYTES = {"f64": 8, "f32": 4, "s32": 4, "u32": 4, "s64": 8, "u64": 8, "pred": 1}
_KINDS = (
    "all-gather",
    "all-reduce",
    "all-to-all",
    "collective-permute",
    "reduce-scatter",
)


def _collectives(hlo: str) -> dict:
    """{kind: [count, bytes]} of the collectives in an optimised HLO text (the
    bytes of each op's result)."""
    found = {}
    pattern = r"= (\(?[^=]*?\)?) (" + "|".join(_KINDS) + r")(?:-start)?\("
    for m in re.finditer(pattern, hlo):
        size = 0
        for dtype, dims in re.findall(r"(\w+)\[([\d,]*)\]", m.group(1)):
            count = 1
            for d in filter(None, dims.split(",")):
                count *= int(d)
            size += count * _BYTES.get(dtype, 4)
        kind = found.setdefault(m.group(2), [0, 0])
        kind[0] += 1
        kind[1] += size
    return found


def _case(particles: int, devices: tuple[int, ...]):
    """The dam break nearest `particles` whose capacity every device count
    divides."""
    import jaxmps

    lcm = 1
    for d in devices:
        lcm = lcm * d // math.gcd(lcm, d)
    base = 0.0146 * (518 / particles) ** 0.5
    for k in range(400):
        spacing = base * (1 - 0.0005 * k)
        case = jaxmps.scenes.dam_break(spacing=spacing)
        if case.scene.capacity % lcm == 0:
            dt = float(case.params.dt)
            return jaxmps.scenes.dam_break(spacing=spacing, dt=dt), spacing
    raise SystemExit(f"no spacing near {base} gives a capacity divisible by {lcm}")


def measure(devices: int, particles: int, counts: tuple[int, ...], steps: int):
    import time

    import jax
    import numpy as np
    from _common import result_name

    import jaxmps

    case, spacing = _case(particles, counts)
    state = jaxmps.shard_particles(case.state, devices=devices)
    args = (case.scene, case.params, state, steps, steps)
    t0 = time.perf_counter()
    lowered = jaxmps.lower_simulate(*args, throw=False)
    program = lowered.compile()
    compile_s = time.perf_counter() - t0
    # The optimised program's text, for its collectives (a second compilation).
    text = lowered._lowered.compile().compiled.as_text()
    runs = []
    for _ in range(3):
        t0 = time.perf_counter()
        out = jax.block_until_ready(program(*args, throw=False))
        runs.append(time.perf_counter() - t0)
    np.save(HERE / f".sharded_position_{devices}.npy", np.asarray(out.state.position))
    row = dict(
        devices=devices,
        capacity=int(case.scene.capacity),
        spacing=spacing,
        steps=steps,
        result=result_name(out.result),
        compile_s=compile_s,
        run_s=min(runs),
        step_ms=1e3 * min(runs) / steps,
        collectives=_collectives(text),
    )
    print(json.dumps(row), flush=True)


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--devices", type=int, nargs="+", default=[1, 2, 4])
    p.add_argument("--particles", type=int, default=2900)
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    counts = tuple(args.devices)
    if args.child is not None:
        measure(args.child, args.particles, counts, args.steps)
        return
    rows = rows_per_device_count(
        __file__,
        counts,
        ["--particles", str(args.particles), "--steps", str(args.steps)]
        + ["--devices", *map(str, counts)],
    )
    import numpy as np

    one = np.load(HERE / f".sharded_position_{counts[0]}.npy")
    for r in rows:
        path = HERE / f".sharded_position_{r['devices']}.npy"
        r["max_position_difference_m"] = float(np.max(np.abs(np.load(path) - one)))
        path.unlink()
    write_rows("sharded_run", args.out, rows, _markdown)


def _markdown(info: dict, rows: list[dict]) -> str:
    base = rows[0]["step_ms"]
    lines = [
        "# One run split over devices (particle axis, XLA's partitioning)",
        "",
        f"Machine: {info['cpu_model']}, {info['cpu_usable']} cores usable, backend "
        f"{info['backend']}; {info['dtype']}. Script: `benchmarks/sharded_run.py`. "
        f"2-D dam break, capacity {rows[0]['capacity']}, {rows[0]['steps']} fixed "
        "steps.",
        "",
        "| devices | compile [s] | ms / step | vs 1 device | max |dx| vs 1 device "
        "[m] | collectives in the program (count, MiB) |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        coll = (
            ", ".join(
                f"{k} {v[0]} ({v[1] / 2**20:.2f})"
                for k, v in sorted(r["collectives"].items())
            )
            or "none"
        )
        lines.append(
            f"| {r['devices']} | {r['compile_s']:.1f} | {r['step_ms']:.2f} | "
            f"{r['step_ms'] / base:.2f} | {r['max_position_difference_m']:.2e} | "
            f"{coll} |"
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
