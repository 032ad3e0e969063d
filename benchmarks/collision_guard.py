"""Cost of the collision guard's wall-plane pass (`CollisionGuard.wall_plane`):
the semi-implicit standard scheme's step with the pass and without it, on the
same scene and state.

Per case, the two versions are compiled once each and then timed alternately
(`--rounds` rounds of best-of-3 calls of `--steps` fixed steps from the scene's
initial state, each after one untimed call), so that a host's drift between sittings
falls on both; the table gives each version's median over the rounds and their
ratio. Compile time is reported apart.

    python benchmarks/collision_guard.py [--steps 50] [--rounds 3]
    (writes results/collision_guard_<backend>.{json,md})
"""

import argparse
import statistics

import equinox as eqx
from _common import fixed_steps, loadavg, time_calls, time_compiled, write_rows

import jaxmps

CASES = {
    "2-D dam break, l0 = 2.5 mm": ("dam_break", dict(spacing=0.0025)),
    "3-D dam break, l0 = 15 mm": ("dam_break", dict(spacing=0.015, dim=3)),
}


def _with_plane(case, on: bool):
    return eqx.tree_at(lambda c: c.scene.collision.wall_plane, case, on)


def measure(label: str, name: str, settings: dict, steps: int, rounds: int) -> dict:
    base = fixed_steps(jaxmps.scenes.build(name, **settings))
    compiled = {}
    for on in (True, False):
        case = _with_plane(base, on)
        compiled[on] = (
            case,
            time_compiled(
                jaxmps.lower_simulate,
                case.scene,
                case.params,
                case.state,
                steps,
                steps,
                jaxmps.frame,
                throw=False,
            ),
        )
    runs = {True: [], False: []}
    for _ in range(rounds):
        for on in (True, False):
            case, timed = compiled[on]
            args = (case.scene, case.params, case.state, steps, steps, jaxmps.frame)
            _, _, times = time_calls(lambda: timed.compiled(*args, throw=False))
            runs[on].append(min(times))
    with_plane, without = (statistics.median(runs[on]) for on in (True, False))
    particles = int(base.state.active.sum())
    return dict(
        label=label,
        particles=particles,
        steps=steps,
        compile_s={
            str(on): round(t.trace_lower_s + t.compile_s, 2)
            for on, (_, t) in compiled.items()
        },
        runs_with_plane_s=runs[True],
        runs_without_s=runs[False],
        ms_per_step_with_plane=1e3 * with_plane / steps,
        ms_per_step_without=1e3 * without / steps,
        ratio=with_plane / without,
        load=loadavg(),
    )


def markdown(info: dict, rows: list[dict]) -> str:
    lines = [
        "# Collision guard: the wall-plane pass's cost",
        "",
        f"Machine: {info}",
        "",
        "| case | particles | steps | compile with / without [s] |"
        " ms/step with the plane (median) | without | ratio | load |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        c = r["compile_s"]
        lines.append(
            f"| {r['label']} | {r['particles']} | {r['steps']} | "
            f"{c['True']} / {c['False']} | {r['ms_per_step_with_plane']:.3f} | "
            f"{r['ms_per_step_without']:.3f} | {r['ratio']:.3f} | {r['load']} |"
        )
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--cases", nargs="+", default=list(CASES))
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    rows = []
    for label in args.cases:
        name, settings = CASES[label]
        rows.append(measure(label, name, settings, args.steps, args.rounds))
        print(rows[-1], flush=True)
    write_rows("collision_guard", args.out, rows, markdown)


if __name__ == "__main__":
    main()
