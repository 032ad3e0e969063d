"""Roofline of `jaxmps`' steps on this host: each stage's time against what the
host's memory system and vector units allow.

Host limits, measured here (best of `--repeats` calls):

* stream bandwidth [GB/s]: copy and triad (a = b + s c) in numpy (one thread)
  and as jitted JAX programs (XLA's CPU threads), at the size of one (n, k) pair
  array of the case (the step's typical operand; it stays in the last-level
  cache) and at `--dram-mib` per array (beyond it);
* gather rate [elements/s]: `field[index]` accumulated into an (n, k) array, over
  the case's own neighbour lists and over as many random indices;
* elementwise peak [flop/s]: a chain of 32 multiply-adds per element of an array
  that stays in the core's cache.

The JAX kernels run 20 times inside one jitted loop, as a step's kernels run
inside the rollout's, so that dispatch does not count.

Per stage of the step: the rollout (`jaxmps.simulate`, fixed steps, from the
state `--start-steps` steps in) is traced with `jax.profiler`; every XLA kernel
that ran is attributed to the stage whose named scope (`jaxmps._step`:
neighbours, predict, collide, advect, surface, pressure, correct, ...) its HLO
metadata names ("other": the rollout's own bookkeeping). For each kernel the
compiled HLO gives the bytes it reads and writes (its operands' and results'
shapes), the elements it gathers and the floating-point operations of its fused
computation (elementwise arithmetic and reductions, one flop per element each).
A stage's limit time is the sum over its kernels and calls of the largest of
bytes / bandwidth, gathers / gather rate and flops / peak, with the JAX
cache-resident rates; its fraction of the limit is limit time / measured time.
XLA's own cost analysis of the compiled rollout (one loop body counted once) is
reported beside the sums as a cross-check.

Usage:
    python benchmarks/roofline.py                          # 25k, both solvers
    python benchmarks/roofline.py --size 7k --solvers explicit --dtype float32
    python benchmarks/roofline.py --start-steps 4000 --out /tmp/roofline_flow

Writes `benchmarks/results/roofline_<backend>.json` and `.md` (override with
`--out`, a path without extension).
"""

import argparse
import collections
import gzip
import json
import re
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
STAGES = (
    "boundaries",
    "coupling",
    "neighbours",
    "predict",
    "porous",
    "collide",
    "advect",
    "surface",
    "pressure",
    "correct",
    "stabilise",
    "outflow",
    "result",
)
BYTES = {"pred": 1, "s8": 1, "u8": 1, "s16": 2, "u16": 2, "f16": 2, "bf16": 2}
BYTES.update({"s32": 4, "u32": 4, "f32": 4, "s64": 8, "u64": 8, "f64": 8})
ARITHMETIC = {
    "add",
    "subtract",
    "multiply",
    "divide",
    "maximum",
    "minimum",
    "negate",
    "abs",
    "sqrt",
    "rsqrt",
    "power",
    "exponential",
    "log",
    "tanh",
}
CONTROL = {"while", "conditional", "call"}
LOOPS = 20
SHAPE = re.compile(r"\b(pred|[suf]\d+|bf16)\[([\d,]*)\]")


# ----------------------------------------------------------------------------- host


def _best(call, repeats: int) -> float:
    call()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        call()
        times.append(time.perf_counter() - t)
    return min(times)


def host_limits(index, dtype: str, dram_mib: int, repeats: int) -> dict:
    """Bandwidths, gather rates and elementwise peak of this host (module doc).
    The JAX kernels run `LOOPS` times inside one jitted loop, as a step's kernels
    run inside the rollout's, so that dispatch does not count."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    size = np.dtype(dtype).itemsize
    n, k = index.shape
    out = {}
    for label, count in (("llc", n * k), ("dram", dram_mib * 2**20 // size)):
        loops = LOOPS if label == "llc" else 4
        b = np.random.default_rng(0).random(count).astype(dtype)
        c, a = b.copy(), np.empty_like(b)
        copy = _best(lambda b=b, a=a: np.copyto(a, b), repeats)
        triad = _best(
            lambda a=a, b=b, c=c: np.add(b, np.multiply(c, 2.5, out=a), out=a),
            repeats,
        )
        out[f"numpy_copy_{label}_GBps"] = 2 * count * size / copy / 1e9
        out[f"numpy_triad_{label}_GBps"] = 3 * count * size / triad / 1e9
        jb, jc = jnp.asarray(b), jnp.asarray(c)
        scale = jax.jit(lambda x: jax.lax.fori_loop(0, loops, lambda i, y: y * 0.5, x))
        triads = jax.jit(
            lambda x, y: jax.lax.fori_loop(0, loops, lambda i, z: x + 0.5 * z, y)
        )
        t_scale = _best(lambda x=jb: scale(x).block_until_ready(), repeats)
        t_triad = _best(lambda x=jb, y=jc: triads(x, y).block_until_ready(), repeats)
        out[f"jax_scale_{label}_GBps"] = loops * 2 * count * size / t_scale / 1e9
        out[f"jax_triad_{label}_GBps"] = loops * 3 * count * size / t_triad / 1e9
        del b, c, a, jb, jc
    field = jnp.asarray(np.random.default_rng(1).random(n + 1).astype(dtype))

    @jax.jit
    def gathers(f, idx):
        def body(i, carry):
            f, acc = carry
            return f + 1e-9, acc + f[idx]

        acc = jnp.zeros(idx.shape, f.dtype)
        return jax.lax.fori_loop(0, LOOPS, body, (f, acc))[1]

    listed = jnp.asarray(index)
    shuffled = jnp.asarray(np.random.default_rng(2).integers(0, n, index.shape))
    for label, idx in (("lists", listed), ("random", shuffled)):
        t = _best(lambda idx=idx: gathers(field, idx).block_until_ready(), repeats)
        out[f"gather_{label}_per_s"] = LOOPS * n * k / t
    x = jnp.asarray(np.random.default_rng(3).random(2**16).astype(dtype))

    def chain(i, y):
        for _ in range(32):
            y = y * 0.999 + 0.5
        return y

    peak = jax.jit(lambda x: jax.lax.fori_loop(0, 10 * LOOPS, chain, x))
    t = _best(lambda: peak(x).block_until_ready(), repeats)
    out["elementwise_flops_per_s"] = 10 * LOOPS * 64 * x.size / t
    return out


# ----------------------------------------------------------------------------- HLO


def _shape_stats(text: str) -> tuple[int, int]:
    """(elements, bytes) of every array shape in `text` (a result or a tuple)."""
    elements = size = 0
    for dtype, dims in SHAPE.findall(text):
        count = 1
        for d in filter(None, dims.split(",")):
            count *= int(d)
        elements += count
        size += count * BYTES.get(dtype, 4)
    return elements, size


def parse_hlo(text: str) -> dict:
    """Per instruction name: op, result (elements, bytes), operand names, the
    computation it calls, and its HLO metadata op_name; per computation, its
    instruction names."""
    instructions, computations, current = {}, {}, None
    header = re.compile(r"^(?:ENTRY )?%?([\w.\-]+) \(.*\) -> .* \{$")
    line_re = re.compile(
        r"^\s*(?:ROOT )?%?([\w.\-]+) = (\(.*?\)|\S+) ([\w\-]+)\((.*?)\)(.*)$"
    )
    for line in text.splitlines():
        h = header.match(line)
        if h:
            current = h.group(1)
            computations[current] = []
            continue
        m = line_re.match(line)
        if not m or current is None:
            continue
        name, shape, op, args, rest = m.groups()
        calls = re.search(r"calls=%?([\w.\-]+)", rest)
        scope = re.search(r'op_name="([^"]+)"', rest)
        dtype = SHAPE.search(shape)
        instructions[name] = dict(
            op=op,
            dtype=dtype.group(1) if dtype else "",
            shape=_shape_stats(shape),
            operands=re.findall(r"%([\w.\-]+)", args),
            calls=calls.group(1) if calls else None,
            scope=scope.group(1) if scope else "",
        )
        computations[current].append(name)
    return dict(instructions=instructions, computations=computations)


def kernel_cost(hlo: dict, name: str) -> dict:
    """Bytes read and written, gathered elements and flops of one kernel."""
    ins = hlo["instructions"]
    me = ins[name]
    size = me["shape"][1] + sum(ins[o]["shape"][1] for o in me["operands"] if o in ins)
    gathers = flops = 0
    body = hlo["computations"].get(me["calls"], []) if me["calls"] else [name]
    for inner in body:
        op, (elements, _) = ins[inner]["op"], ins[inner]["shape"]
        floating = ins[inner]["dtype"].startswith(("f", "bf"))
        if op == "gather":
            gathers += elements
        elif op in ARITHMETIC and floating:
            flops += elements
        elif op == "reduce" and floating:
            operand = ins[inner]["operands"][0]
            flops += ins[operand]["shape"][0] if operand in ins else elements
    return dict(bytes=size, gathers=gathers, flops=flops)


def stage_of(scope: str) -> str:
    """The step stage a kernel's op_name lies in ("other" outside any)."""
    for part in scope.split("/"):
        if part in STAGES:
            return part
    return "other"


# ----------------------------------------------------------------------------- run


def trace_rollout(case, steps: int, start_steps: int) -> dict:
    """Time the rollout, then trace one call of it: per kernel, its calls and
    time, with the compiled HLO's costs."""
    import equinox as eqx
    import jax

    import jaxmps

    scene, params, state = case.scene, case.params, case.state
    if start_steps:
        state = jaxmps.simulate(
            scene, params, state, start_steps, start_steps, _time, throw=False
        ).state

    run = eqx.filter_jit(
        lambda p, s: jaxmps.simulate(scene, p, s, steps, steps, _time, throw=False)
    )
    compiled = run.lower(params, state).compile()
    out = jax.block_until_ready(run(params, state))
    run_s = _best(lambda: jax.block_until_ready(run(params, state)), 2)
    with tempfile.TemporaryDirectory() as d:
        with jax.profiler.trace(d, create_perfetto_trace=True):
            jax.block_until_ready(run(params, state))
        trace = next(Path(d).rglob("*perfetto_trace.json.gz"))
        events = json.load(gzip.open(trace))
    events = events["traceEvents"] if isinstance(events, dict) else events
    inner = getattr(compiled, "compiled", compiled)
    hlo = parse_hlo(inner.as_text())
    xla = inner.cost_analysis()
    xla = xla[0] if isinstance(xla, list) else xla
    time_us, calls = collections.Counter(), collections.Counter()
    for e in events:
        name = e.get("name")
        if e.get("ph") == "X" and name in hlo["instructions"]:
            if hlo["instructions"][name]["op"] not in CONTROL:
                time_us[name] += e.get("dur", 0)
                calls[name] += 1
    kernels = []
    for name, us in time_us.items():
        cost = kernel_cost(hlo, name)
        kernels.append(
            dict(
                name=name,
                stage=stage_of(hlo["instructions"][name]["scope"]),
                calls=calls[name],
                time_s=us * 1e-6,
                **{key: value * calls[name] for key, value in cost.items()},
            )
        )
    return dict(
        run_s=run_s,
        result=jaxmps._result.result_name(out.result),
        kernels=kernels,
        xla_cost={k: float(xla[k]) for k in ("flops", "bytes accessed") if k in xla},
    )


def _time(scene, state):
    del scene
    return state.time


def stage_table(kernels: list[dict], limits: dict, particle_steps: float) -> list:
    """Per stage: time, bytes, gathers and flops per particle-step, and the
    fraction of the limit (module doc)."""
    bandwidth = limits["jax_triad_llc_GBps"] * 1e9
    gather = limits["gather_lists_per_s"]
    peak = limits["elementwise_flops_per_s"]
    stages = collections.defaultdict(lambda: collections.Counter())
    for k in kernels:
        bound = max(k["bytes"] / bandwidth, k["gathers"] / gather, k["flops"] / peak)
        row = stages[k["stage"]]
        row.update(
            time_s=k["time_s"],
            bytes=k["bytes"],
            gathers=k["gathers"],
            flops=k["flops"],
            limit_s=bound,
            kernels=1,
        )
    rows = []
    for stage, row in stages.items():
        rows.append(
            dict(
                stage=stage,
                kernels=row["kernels"],
                time_s=row["time_s"],
                bytes_per_ps=row["bytes"] / particle_steps,
                gathers_per_ps=row["gathers"] / particle_steps,
                flops_per_ps=row["flops"] / particle_steps,
                limit_s=row["limit_s"],
                fraction=row["limit_s"] / row["time_s"] if row["time_s"] else None,
            )
        )
    order = {s: i for i, s in enumerate(STAGES + ("other",))}
    return sorted(rows, key=lambda r: order.get(r["stage"], len(order)))


def measure(size: int, solver: str, dtype: str, args) -> dict:
    """One (size, solver) row, in this process (dtype set by `main`)."""
    sys.path.insert(0, str(HERE))
    from _common import fixed_steps

    case = fixed_steps(_dam_break(size, solver, args.dim))
    traced = trace_rollout(case, args.steps, args.start_steps)
    n = case.scene.capacity
    particle_steps = n * args.steps
    return dict(
        size=size,
        solver=solver,
        dtype=dtype,
        dim=args.dim,
        particles=n,
        max_neighbours=case.scene.max_neighbours,
        steps=args.steps,
        start_steps=args.start_steps,
        **traced,
        ms_per_step=traced["run_s"] / args.steps * 1e3,
        particle_steps_per_s=particle_steps / traced["run_s"],
        traced_s=sum(k["time_s"] for k in traced["kernels"]),
    )


def _dam_break(size: int, solver: str, dim: int):
    """The dam break of about `size` particles: in 2-D the side-by-side's case (m
    particles across the column), in 3-D the scaling benchmark's."""
    import jaxmps

    if dim == 2:
        from side_by_side import COLUMN_WIDTH, jaxmps_match

        m, _ = jaxmps_match(size, solver)
        return jaxmps.scenes.dam_break(spacing=COLUMN_WIDTH / m, solver=solver)
    from scaling import spacing_for

    spacing = spacing_for(size, dim, solver)
    return jaxmps.scenes.dam_break(spacing=spacing, solver=solver, dim=dim)


def case_lists(size: int, solver: str, dim: int):
    """The neighbour lists of the case's initial state (for the gather rate)."""
    import jaxmps

    case = _dam_break(size, solver, dim)
    scene, state = case.scene, case.state
    return jaxmps.neighbours.build(
        scene.grid,
        state.position,
        state.active,
        scene.max_neighbours,
        scene.r_e,
        scene.neighbour_skin,
    ).index


def markdown(info: dict, rows: list[dict]) -> str:
    limits = rows[0]["limits"]
    lines = [
        f"# Roofline: the {rows[0].get('dim', 2)}-D dam break's steps against "
        "this host's limits",
        "",
        f"- machine: {info.get('platform')}, {info.get('cpu_model')}, "
        f"{info.get('cpu_usable')} usable cores",
        f"- jax {info.get('jax')}; git {info.get('git_commit')}"
        + (" (uncommitted changes)" if info.get("git_dirty_tracked") else ""),
        "- the host limits move between sittings (the JAX LLC triad read 31-51 "
        "GB/s, the scale 39-70 GB/s in three sittings of this session), so a "
        "fraction is good to about +-30 %; above 100 % the byte count of a "
        "kernel is too high (its operands are counted whole, where a gather "
        "reads part of its table)",
        "- produced by `benchmarks/roofline.py` (its docstring says how); "
        "times are one profiled call of the rollout (the profiler adds a little), "
        "the ms/step column the best of two unprofiled calls",
        "",
        "## Host limits",
        "",
        "| measure | value |",
        "|---|---|",
    ]
    for key, value in limits.items():
        unit = "GB/s" if key.endswith("GBps") else "/s"
        shown = value if unit == "GB/s" else f"{value:.3g}"
        lines.append(
            f"| {key} | {shown:.3g} {unit} |"
            if unit == "GB/s"
            else f"| {key} | {shown} |"
        )
    for r in rows:
        lines += [
            "",
            f"## {r['solver']}, {r['particles']} particles ({r['max_neighbours']} "
            f"slots), {r['dtype']}, "
            f"{r['steps']} steps from step {r['start_steps']}",
            "",
            f"{r['ms_per_step']:.2f} ms/step, {r['particle_steps_per_s']:.3g} "
            f"particle-steps/s; traced kernels {r['traced_s'] / r['steps'] * 1e3:.2f} "
            f"ms/step; XLA cost analysis of the rollout program: "
            + ", ".join(f"{k} {v:.3g}" for k, v in r["xla_cost"].items()),
            "",
            "| stage | kernels | ms/step | share | bytes / p-step | gathers / p-step "
            "| flops / p-step | limit ms/step | fraction of limit |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        total = sum(s["time_s"] for s in r["stages"])
        for s in r["stages"]:
            ms = s["time_s"] / r["steps"] * 1e3
            lines.append(
                f"| {s['stage']} | {s['kernels']} | {ms:.2f} "
                f"| {s['time_s'] / total:.0%} | {s['bytes_per_ps']:.0f} "
                f"| {s['gathers_per_ps']:.0f} | {s['flops_per_ps']:.0f} "
                f"| {s['limit_s'] / r['steps'] * 1e3:.3f} | {s['fraction']:.0%} |"
            )
        top = sorted(r["kernels"], key=lambda k: -k["time_s"])[:8]
        lines += ["", "Slowest kernels:", ""]
        for k in top:
            lines.append(
                f"- {k['name']} ({k['stage']}): {k['time_s'] / r['steps'] * 1e3:.2f} "
                f"ms/step, {k['calls'] / r['steps']:.1f} calls/step"
            )
    return "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", default="25k", help="particles, e.g. 7k or 25000")
    p.add_argument("--dim", type=int, default=2, choices=(2, 3))
    p.add_argument("--solvers", nargs="+", default=["explicit", "semi_implicit"])
    p.add_argument("--dtype", choices=("float32", "float64"), default="float64")
    p.add_argument("--steps", type=int, default=100, help="steps traced")
    p.add_argument("--start-steps", type=int, default=0, help="steps run first")
    p.add_argument("--dram-mib", type=int, default=1024, help="array size beyond LLC")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path, default=None, help="path without extension")
    args = p.parse_args()

    import jax

    jax.config.update("jax_enable_x64", args.dtype == "float64")
    sys.path.insert(0, str(HERE))
    from _common import write_rows
    from side_by_side import parse_size

    size = parse_size(args.size)
    limits = host_limits(
        case_lists(size, args.solvers[0], args.dim),
        args.dtype,
        args.dram_mib,
        args.repeats,
    )
    print(json.dumps(limits, indent=1))
    rows = []
    for solver in args.solvers:
        row = measure(size, solver, args.dtype, args)
        row["limits"] = limits
        row["stages"] = stage_table(
            row["kernels"], limits, row["particles"] * row["steps"]
        )
        print(f"{solver}: {row['ms_per_step']:.2f} ms/step")
        for s in row["stages"]:
            print(
                f"  {s['stage']:11s} {s['time_s'] / row['steps'] * 1e3:7.2f} ms/step"
                f"  limit {s['limit_s'] / row['steps'] * 1e3:7.3f}"
                f"  fraction {s['fraction']:.0%}"
            )
        rows.append(row)
    write_rows("roofline", args.out, rows, markdown)


if __name__ == "__main__":
    main()
