"""Step time vs particle count (2-D or 3-D dam break), per solver, with its log-log
slope.

Per size (`jaxmps.scenes.dam_break` at the spacing giving about that many particles,
walls and dummies included; the column is first advanced 20 steps so that it moves):
ms per step of a compiled `--steps`-step rollout (best of 2 after a warm-up call,
compile timed apart), particle-steps/s, CG iterations per step (semi-implicit), and
the cost of a neighbour search against the step's (a build jitted alone, times the
searches a step makes at most, over the step time: one when the lists are carried
from step to step, `Scene.neighbour_skin` > 0, the default, two without; a step
with carried lists searches only once some pair has moved by the skin since the
last search, so above 100 % most steps searched not at all). The slope is the
least-squares fit of log(ms/step) on log(particles) over all sizes.

    python benchmarks/scaling.py                       # float32, 1k-100k, ~10 min
    python benchmarks/scaling.py --sizes 1000 10000 --steps 10 --x64
    python benchmarks/scaling.py --dim 3 --sizes 3000 30000 300000 --solvers explicit
    python benchmarks/scaling.py --sizes 7000 --solvers semi_implicit \
        --scheme standard_ds

`--scheme` is the semi-implicit rows' scheme (a scene setting: `standard`, the
default, `standard_ds`, `high_accuracy`, `standard_mps`).

Writes results/scaling_<cpu|gpu>.{json,md} (2-D) or scaling_3d_<cpu|gpu> (3-D).
"""

import argparse
import json
import sys
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def spacing_for(target: int, dim: int, solver: str) -> float:
    """The dam-break spacing whose capacity is about `target` particles (the count
    scales as spacing^-dim; two corrections from a coarse reference)."""
    import jaxmps

    spacing = 0.146 / (20 if dim == 2 else 8)
    for _ in range(2):
        case = jaxmps.scenes.dam_break(spacing=spacing, solver=solver, dim=dim)
        spacing *= (case.scene.capacity / target) ** (1 / dim)
    return spacing


def measure(
    solver: str, target: int, steps: int, dim: int = 2, scheme: str = "standard"
) -> dict:
    from _common import fixed_steps, time_compiled
    from step_throughput import observe_time

    import jaxmps

    spacing = spacing_for(target, dim, solver)
    if solver == "explicit":
        scheme = "standard"
    case = fixed_steps(
        jaxmps.scenes.dam_break(spacing=spacing, solver=solver, dim=dim, scheme=scheme)
    )
    scene, params = case.scene, case.params
    state = jaxmps.simulate(scene, params, case.state, 20, 20, throw=False).state
    args = (scene, params, state, steps, steps, observe_time)
    timed = time_compiled(jaxmps.lower_simulate, *args, repeats=2, throw=False)
    compile_s = timed.trace_lower_s + timed.compile_s
    run = timed.run_s_best
    _, info = eqx.filter_jit(jaxmps.step)(scene, params, state)

    def build(x):
        nb = jaxmps.neighbours.build(
            scene.grid,
            x,
            state.active,
            scene.max_neighbours,
            scene.r_e + scene.neighbour_skin,
        )
        return nb.index

    # With carried lists a step searches at most once (at its predicted positions,
    # when some pair has moved by the skin since the last search: make_scene's
    # `neighbour_skin`), without them twice: the share is an upper bound.
    searches = 1 if scene.neighbour_skin > 0 else 2

    jitted = jax.jit(build)
    build_s = time_compiled(jitted.lower, state.position, repeats=5).run_s_best
    ms = 1e3 * run / steps
    row = {
        "dim": dim,
        "solver": solver,
        "scheme": scheme,
        "spacing": spacing,
        "particles": int(scene.capacity),
        "steps": steps,
        "compile_s": compile_s,
        "ms_per_step": ms,
        "particle_steps_per_s": scene.capacity * steps / run,
        "cg_iterations": int(info.pressure_iterations),
        "build_ms": 1e3 * build_s,
        "searches_per_step": searches,
        "build_share": searches * 1e3 * build_s / ms,
    }
    print(
        f"{solver:14s} {scheme:13s} n={row['particles']:7d} {ms:9.2f} ms/step "
        f"{row['particle_steps_per_s']:.3g} p-steps/s CG {row['cg_iterations']:4d} "
        f"builds {100 * row['build_share']:.0f} % compile {compile_s:.1f} s",
        flush=True,
    )
    return row


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--sizes", type=int, nargs="+", default=[1000, 3000, 10000, 30000, 100000]
    )
    p.add_argument("--solvers", nargs="+", default=["explicit", "semi_implicit"])
    p.add_argument("--steps", type=int, default=20)
    p.add_argument("--x64", action="store_true")
    p.add_argument("--dim", type=int, default=2, choices=[2, 3])
    p.add_argument("--scheme", default="standard")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    jax.config.update("jax_enable_x64", args.x64)
    from _common import loadavg, machine_info

    info = machine_info()
    rows = [
        measure(s, n, args.steps, args.dim, args.scheme)
        for s in args.solvers
        for n in args.sizes
    ]
    slopes = {}
    for s in args.solvers:
        sel = [r for r in rows if r["solver"] == s]
        x = np.log([r["particles"] for r in sel])
        y = np.log([r["ms_per_step"] for r in sel])
        slopes[s] = float(np.polyfit(x, y, 1)[0]) if len(sel) > 1 else None
    info["loadavg_1min_end"] = loadavg()
    data = {"machine": info, "rows": rows, "slopes": slopes}
    tag = "" if args.dim == 2 else "3d_"
    out = args.out or HERE / "results" / f"scaling_{tag}{jax.default_backend()}"
    out.with_suffix(".json").write_text(json.dumps(data, indent=1))
    lines = [
        f"# Step time vs particle count: {args.dim}-D dam break",
        "",
        f"- {info['platform']}, {info['cpu_model']}, {info['cpu_usable']} cores; "
        f"jax {info['jax']}; {info['dtype']}; git {info['git_commit']}",
        f"- 1-min load average {info['loadavg_1min_start']} at start, "
        f"{info['loadavg_1min_end']} at end",
        f"- {args.steps} steps after 20; best of 2 after a warm-up call",
        "- build share: one search (jitted alone) per step at most, over the step "
        "time; a step with carried lists searches only once some pair has moved "
        "by the skin, so above 100 % most steps did not search",
        "",
        "| solver | scheme | particles | ms/step | particle-steps/s | CG it. | "
        "build share | compile [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['solver']} | {r['scheme']} | {r['particles']} | "
            f"{r['ms_per_step']:.2f} | "
            f"{r['particle_steps_per_s']:.3g} | {r['cg_iterations']} | "
            f"{100 * r['build_share']:.0f} % | {r['compile_s']:.1f} |"
        )
    lines += ["", "log-log slope of ms/step on particles: "]
    lines[-1] += ", ".join(f"{s} {v:.2f}" for s, v in slopes.items() if v is not None)
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
