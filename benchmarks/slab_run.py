"""One explicit run split over devices two ways: XLA's partitioning of the
particle axis (`jaxmps.shard_particles`) and slabs with a halo exchanged by
`shard_map` (`jaxmps.simulate_slabs`), against the one-device run.

The case: a 2-D explicit (E-MPS) dam break, a column 0.4 m wide in a 1.6 m tank
(long enough for four slabs wider than the halo), fixed steps of the scene's
largest step, `--particles` near 3,000 by default (a spacing whose capacity the
device counts divide). Per device count, in a process of its own (CPU devices
forced with XLA_FLAGS, or the GPUs there are): compile time, run time per step
(best of 3; for the slabs the device program alone, the host's layout and
reassembly timed apart, and the compile time that of the first call less a
later one's), the largest difference of the positions from the
one-device run, the collectives in the optimised program (count and MiB by
kind; those in the step loop run once per step), and for the slabs the slots
each device steps (its slab's slots plus two halos) against an even share.

Usage:
    python benchmarks/slab_run.py                    # CPU, 1/2/4 forced devices
    python benchmarks/slab_run.py --particles 12000

Writes `benchmarks/results/slab_run_<backend>.{json,md}`.
"""

import argparse
import json
import math
from pathlib import Path

from _common import rows_per_device_count, write_rows
from sharded_run import _collectives

HERE = Path(__file__).resolve().parent
_SHAPE = dict(solver="explicit", column_width=0.4, tank_length=1.6)


def _case(particles: int, devices: tuple[int, ...]):
    """The explicit dam break nearest `particles` whose capacity every device
    count divides, with its largest step fixed."""
    import jaxmps

    lcm = 1
    for d in devices:
        lcm = lcm * d // math.gcd(lcm, d)
    base = 0.01 * (1922 / particles) ** 0.5
    for k in range(400):
        spacing = base * (1 - 0.0005 * k)
        case = jaxmps.scenes.dam_break(spacing=spacing, **_SHAPE)
        if case.scene.capacity % lcm == 0:
            dt = float(case.params.dt)
            return jaxmps.scenes.dam_break(spacing=spacing, dt=dt, **_SHAPE), spacing
    raise SystemExit(f"no spacing near {base} gives a capacity divisible by {lcm}")


def _timed(call, repeats=3):
    import time

    import jax

    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(call())
        runs.append(time.perf_counter() - t0)
    return out, min(runs)


def measure(devices: int, particles: int, counts: tuple[int, ...], steps: int):
    import time

    import numpy as np
    from _common import result_name

    import jaxmps
    from jaxmps import _slabs

    case, spacing = _case(particles, counts)
    scene, params = case.scene, case.params
    common = dict(capacity=int(scene.capacity), spacing=spacing, steps=steps)

    # XLA's partitioning of the particle axis.
    state = jaxmps.shard_particles(case.state, devices=devices)
    args = (scene, params, state, steps, steps)
    t0 = time.perf_counter()
    lowered = jaxmps.lower_simulate(*args, throw=False)
    program = lowered.compile()
    compile_s = time.perf_counter() - t0
    text = lowered._lowered.compile().compiled.as_text()
    out, run_s = _timed(lambda: program(*args, throw=False))
    np.save(HERE / f".slab_xla_{devices}.npy", np.asarray(out.state.position))
    row = dict(
        common,
        method="xla",
        devices=devices,
        result=result_name(out.result),
        compile_s=compile_s,
        step_ms=1e3 * run_s / steps,
        collectives=_collectives(text),
    )
    print(json.dumps(row), flush=True)

    # Slabs with a halo.
    t0 = time.perf_counter()
    run = jaxmps.simulate_slabs(scene, params, case.state, steps, devices=devices)
    first_s = time.perf_counter() - t0
    np.save(HERE / f".slab_slabs_{devices}.npy", np.asarray(run.state.position))
    mesh = jaxmps.member_mesh(devices=devices)
    mesh = _slabs.Mesh(mesh.devices.reshape(-1), (_slabs.SLABS,))
    halo = _slabs.slab_halo(scene)
    layout = _slabs._layout(case.state, devices, halo, 1.5, None)
    inputs = (scene, params, mesh, layout.shape(halo), steps)
    inputs += _slabs._place(layout, mesh, case.state)
    text = _slabs._program.lower(*inputs).lowered.compile().as_text()
    _, run_s = _timed(lambda: _slabs._program(*inputs))
    t0 = time.perf_counter()
    jaxmps.simulate_slabs(scene, params, case.state, steps, devices=devices)
    whole_s = time.perf_counter() - t0
    compile_s = max(first_s - whole_s, 0.0)
    active = int(np.sum(np.asarray(case.state.active)))
    stepped = layout.slots + 2 * layout.halo_slots * (devices > 1)
    row = dict(
        common,
        method="slabs",
        devices=devices,
        result=result_name(run.result),
        compile_s=compile_s,
        first_call_s=first_s,
        host_s=max(whole_s - run_s, 0.0),
        step_ms=1e3 * run_s / steps,
        collectives=_collectives(text),
        halo_m=halo,
        slots=layout.slots,
        halo_slots=layout.halo_slots,
        stepped_per_device=stepped,
        even_share=active / devices,
        peak_owned=np.asarray(run.peak_owned).tolist(),
        peak_halo=np.asarray(run.peak_halo).tolist(),
        cuts=[float(c) for c in run.cuts[1:-1]],
    )
    print(json.dumps(row), flush=True)


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--devices", type=int, nargs="+", default=[1, 2, 4])
    p.add_argument("--particles", type=int, default=3000)
    p.add_argument("--steps", type=int, default=200)
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

    one = np.load(HERE / f".slab_xla_{counts[0]}.npy")
    for r in rows:
        path = HERE / f".slab_{r['method']}_{r['devices']}.npy"
        r["max_position_difference_m"] = float(np.max(np.abs(np.load(path) - one)))
    for r in rows:
        (HERE / f".slab_{r['method']}_{r['devices']}.npy").unlink(missing_ok=True)
    write_rows("slab_run", args.out, rows, _markdown)


def _markdown(info: dict, rows: list[dict]) -> str:
    base = rows[0]["step_ms"]
    lines = [
        "# One explicit run split over devices: XLA's partitioning against slabs "
        "with a halo",
        "",
        f"Machine: {info['cpu_model']}, {info['cpu_usable']} cores usable, backend "
        f"{info['backend']}; {info['dtype']}. Script: `benchmarks/slab_run.py`. "
        f"2-D explicit dam break (column 0.4 m in a 1.6 m tank), capacity "
        f"{rows[0]['capacity']}, l0 = {rows[0]['spacing'] * 1e3:.2f} mm, "
        f"{rows[0]['steps']} fixed steps. Times against the one-device run "
        "(`simulate`, which carries its neighbour lists; the slabs search twice "
        "per step).",
        "",
        "| method | devices | compile [s] | ms / step | vs 1 device | max |dx| vs "
        "1 device [m] | collectives in the program (count, MiB) | slots stepped "
        "per device / even share |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        coll = (
            ", ".join(
                f"{k} {v[0]} ({v[1] / 2**20:.3f})"
                for k, v in sorted(r["collectives"].items())
            )
            or "none"
        )
        share = (
            f"{r['stepped_per_device']} / {r['even_share']:.0f}"
            if r["method"] == "slabs"
            else "-"
        )
        lines.append(
            f"| {r['method']} | {r['devices']} | {r['compile_s']:.1f} | "
            f"{r['step_ms']:.2f} | {r['step_ms'] / base:.2f} | "
            f"{r['max_position_difference_m']:.2e} | {coll} | {share} |"
        )
    slabs = [r for r in rows if r["method"] == "slabs"]
    if slabs:
        r = slabs[-1]
        lines += [
            "",
            f"Slabs: halo {r['halo_m'] * 1e3:.1f} mm; over {r['devices']} devices "
            f"cuts at x = {', '.join(f'{c:.3f}' for c in r['cuts'])} m, most "
            f"particles held {r['peak_owned']}, most sent to one halo "
            f"{r['peak_halo']}; host-side layout and reassembly "
            f"{r['host_s']:.2f} s per call.",
        ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
