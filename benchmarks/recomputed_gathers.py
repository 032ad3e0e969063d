"""Gathers that recompute what they read: the fusions of a compiled rollout in
which a gather's operand is an expression computed inside the same fusion from
a reduction, another gather, a dot, a scatter or a sort, or by `CHAIN` or more
computing instructions, with their traced time.

XLA's CPU backend fuses a cheap-looking producer into the gather that reads it
and then evaluates the producer once per gathered element: a per-particle row
count read by every pair slot costs the row's work k times over (k slots), a
multigrid level's correction read by each finer cell recomputes its stencil
product. Such a field is written out first with `jaxmps._numerics.materialised`
(benchmarks/NOTES.md §23). This script finds them: a scene is rolled out
`--warm` steps, `--steps` steps are compiled, run once untimed and traced once
with `jax.profiler`, and every fusion of the trace is matched to its HLO
computation. A gather of a parameter (a field already in memory) is not listed,
nor one of a cheap elementwise expression (a mask, a sum of two fields).

Run: python benchmarks/recomputed_gathers.py [--scenes dam_break:solver=explicit,
floating_box:spacing=0.005] [--warm 50] [--steps 20] [--x64] [--out NAME]
(writes results/recomputed_gathers_cpu.{md,json})
"""

import argparse
import collections
import glob
import gzip
import json
import re
import shutil
import tempfile

import jax
from _common import HERE, fixed_steps, machine_info

import jaxmps
from jaxmps._simulate import _prepared, _simulate

HEAVY = ("reduce", "gather", "dot", "reduce-window", "scatter", "sort")
# Instructions that move or relabel data without computing: not counted.
FREE = (
    "bitcast",
    "reshape",
    "broadcast",
    "constant",
    "parameter",
    "slice",
    "copy",
    "transpose",
    "iota",
)
# An operand computed by this many instructions or more inside the fusion is
# listed even without a heavy one (the multigrid's cell index took 6, a
# V-cycle level's correction 23).
CHAIN = 6
DEFAULT_SCENES = (
    "dam_break:solver=explicit,"
    "dam_break:solver=semi_implicit,"
    "floating_box:spacing=0.005"
)


def observe_time(scene, state):
    del scene
    return state.time


def parse_scene(text: str) -> tuple[str, dict]:
    """`name:key=value:key=value` -> (name, settings); numbers become floats."""
    name, *pairs = text.split(":")
    settings = {}
    for pair in pairs:
        key, value = pair.split("=")
        try:
            settings[key] = float(value)
        except ValueError:
            settings[key] = value
    return name, settings


def _computations(hlo: str) -> dict[str, dict[str, tuple[str, list[str]]]]:
    """Each computation's instructions: name -> (opcode, operand names)."""
    found = {}
    pattern = r"^%?([\w.\-]+) (?:\([^\n]*\))? ?-> [^\n]*\{\n(.*?)\n\}"
    for match in re.finditer(pattern, hlo, re.M | re.S):
        body = {}
        for line in match.group(2).splitlines():
            m = re.match(r"\s*(?:ROOT )?%?([\w.\-]+) = \S+ ([\w\-]+)\((.*?)\)", line)
            if m:
                body[m.group(1)] = (m.group(2), re.findall(r"%([\w.\-]+)", m.group(3)))
        found[match.group(1)] = body
    return found


def recomputing_fusions(hlo: str) -> dict[str, list[str]]:
    """Fused computations with a gather whose operand is computed inside them
    from one of `HEAVY`, or by `CHAIN` or more computing instructions:
    computation -> what was found (the heavy opcodes, or "N ops")."""
    out = {}
    for name, body in _computations(hlo).items():
        for opcode, operands in body.values():
            if opcode != "gather":
                continue
            stack, seen, heavy, count = [operands[0]], set(), set(), 0
            while stack:
                x = stack.pop()
                if x in seen or x not in body:
                    continue
                seen.add(x)
                op, args = body[x]
                if op in HEAVY:
                    heavy.add(op)
                count += op not in FREE
                stack.extend(args)
            if count >= CHAIN:
                heavy.add(f"{count} ops")
            if heavy:
                out.setdefault(name, set()).update(heavy)
    return {k: sorted(v) for k, v in out.items()}


def measure(name: str, settings: dict, warm: int, steps: int) -> dict:
    case = fixed_steps(getattr(jaxmps.scenes, name)(**settings))
    scene, params, state = case.scene, case.params, case.state
    if warm:
        state = jaxmps.simulate(
            scene, params, state, warm, warm, observe_time, throw=False
        ).state
    args, kwargs = _prepared(
        scene, params, state, steps, None, observe_time, throw=False
    )
    compiled = _simulate.lower(*args, **kwargs).compile()
    hlo = compiled.compiled.as_text()
    jax.block_until_ready(compiled(*args, **kwargs))
    fusions, scopes = {}, {}
    for line in hlo.splitlines():
        m = re.match(
            r"\s*(?:ROOT )?%?([\w.\-]+) = \S+ fusion\(.*?calls=%?([\w.\-]+)", line
        )
        if m:
            fusions[m.group(1)] = m.group(2)
            op = re.search(r'op_name="([^"]+)"', line)
            scopes[m.group(1)] = "/".join(op.group(1).split("/")[-4:]) if op else ""
    heavy = recomputing_fusions(hlo)
    folder = tempfile.mkdtemp(prefix="recomputed_gathers_")
    try:
        jax.profiler.start_trace(folder, create_perfetto_trace=True)
        jax.block_until_ready(compiled(*args, **kwargs))
        jax.profiler.stop_trace()
        trace = glob.glob(f"{folder}/**/*.trace.json.gz", recursive=True)[0]
        events = json.load(gzip.open(trace))["traceEvents"]
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    total, listed, count = 0.0, collections.Counter(), collections.Counter()
    for e in events:
        if e.get("ph") != "X" or e.get("name") not in fusions:
            continue
        total += e["dur"]
        if fusions[e["name"]] in heavy:
            listed[e["name"]] += e["dur"]
            count[e["name"]] += 1
    rows = [
        {
            "fusion": f,
            "reads": heavy[fusions[f]],
            "scope": scopes[f],
            "ms_per_step": 1e-3 * us / steps,
            "calls_per_step": count[f] / steps,
        }
        for f, us in listed.most_common()
    ]
    return {
        "scene": name,
        "settings": settings,
        "capacity": int(scene.capacity),
        "steps": steps,
        "fusion_ms_per_step": 1e-3 * total / steps,
        "recomputing": rows,
    }


def markdown(runs: list[dict], info: dict) -> str:
    lines = [
        "# Gathers that recompute what they read",
        "",
        f"Machine: {info}",
        "",
        "Per scene: the traced time of every fusion of the step, and of those in "
        "which a gather reads an operand computed inside the fusion from a "
        "reduction, gather, dot, scatter or sort (`benchmarks/recomputed_gathers.py`;"
        " ms per step, one traced call).",
        "",
        "| scene | settings | particles | all fusions | recomputing | fusion "
        "| reads | scope |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        listed = r["recomputing"] or [None]
        for i, row in enumerate(listed):
            head = (
                f"| {r['scene']} | {r['settings']} | {r['capacity']} | "
                f"{r['fusion_ms_per_step']:.1f} | "
                if i == 0
                else "| | | | | "
            )
            if row is None:
                lines.append(head + "none | | | |")
                continue
            lines.append(
                head + f"{row['ms_per_step']:.2f} ({row['calls_per_step']:.2f}/step) "
                f"| {row['fusion']} | {', '.join(row['reads'])} | {row['scope']} |"
            )
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=DEFAULT_SCENES)
    parser.add_argument("--warm", type=int, default=50)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--x64", action="store_true", help="run in float64")
    parser.add_argument("--out", default="recomputed_gathers_cpu")
    args = parser.parse_args()
    if args.x64:
        jax.config.update("jax_enable_x64", True)
    runs = []
    for text in args.scenes.split(","):
        name, settings = parse_scene(text)
        if name not in jaxmps.scenes.available():
            raise SystemExit(
                f"Unknown scene {name!r}; --scenes takes names of "
                f"jaxmps.scenes.available(): {sorted(jaxmps.scenes.available())}"
            )
        runs.append(measure(name, settings, args.warm, args.steps))
        print(json.dumps({k: v for k, v in runs[-1].items() if k != "recomputing"}))
    info = machine_info()
    path = HERE / "results" / args.out
    path.with_suffix(".md").write_text(markdown(runs, info))
    path.with_suffix(".json").write_text(
        json.dumps({"machine": info, "runs": runs}, indent=1)
    )
    print(path.with_suffix(".md").read_text())


if __name__ == "__main__":
    main()
