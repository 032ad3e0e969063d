"""Does the pressure solve's tolerance move the accuracy? An ensemble.

The semi-implicit solver solves its pressure system to `SemiImplicit.rtol` (default
1e-9 in float64). A looser tolerance takes fewer CG iterations; whether it costs
accuracy is a question a single run cannot answer, because a particle flow
amplifies round-off: the same run with the fluid's initial positions moved by
1e-9 m gives another period. So each (spacing, rtol) is run with `--members`
initial states: the unperturbed one (member 0) and members whose fluid positions
are moved by a normal 1e-9 m perturbation (seed = member index), and the mean and
spread of the period error over the members are compared between tolerances.

Case: `accuracy_vs_cost.py`'s standing wave (0.4 m pool, 0.2 m deep, A = 2 cm, to
1.6 s, period of the cos(2 pi x / L) mode from its zero crossings), standard
semi-implicit scheme, float64, fixed by `accuracy_vs_cost.run_case`.

Usage:
    python validation/solve_tolerance.py          # 1 cm and 5 mm, 4 members (~20 min)
    python validation/solve_tolerance.py --spacings 0.01 --rtols 1e-9 1e-6

Writes `validation/results/solve_tolerance_<cpu|gpu>.{json,md}` (override with --out).
"""

import argparse
import json
import math
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import accuracy_vs_cost as acc  # noqa: E402
import equinox as eqx  # noqa: E402
import numpy as np  # noqa: E402
from _common import machine_info  # noqa: E402

import jaxmps  # noqa: E402

HERE = Path(__file__).resolve().parent
PERTURBATION = 1e-9  # [m], standard deviation of the fluid positions' offsets
SCENES = {"standing_wave": "standing_wave", "hydrostatic": "hydrostatic"}
# What each case measures (`accuracy_vs_cost.run_case`'s record); the first is
# tabulated per member.
MEASURES = {
    "standing_wave": ("rel_period", "final_amplitude"),
    "hydrostatic": ("noise", "err_probe_y0"),
}
LABELS = {
    "rel_period": "period error",
    "final_amplitude": "amplitude at the end / A",
    "noise": "pressure noise (std / reference)",
    "err_probe_y0": "|mean bottom pressure error|",
}


def _member_case(build, member: int):
    """The scene `build` with its fluid moved by PERTURBATION (member > 0)."""

    def case(**config):
        out = build(**config)
        if member == 0:
            return out
        rng = np.random.default_rng(member)
        fluid = np.asarray(out.state.kind == int(jaxmps.Kind.FLUID))[:, None]
        offset = rng.normal(0.0, PERTURBATION, out.state.position.shape) * fluid
        return eqx.tree_at(lambda c: c.state.position, out, out.state.position + offset)

    return case


def run(case: str, method: str, spacing: float, rtol: float, member: int) -> dict:
    args = argparse.Namespace(repeats=1, max_timed_s=0.0)
    original = dict(acc.METHOD)
    acc.METHOD[method] = {**acc.METHOD[method], "rtol": rtol}
    scene_name = SCENES[case]
    build = getattr(jaxmps.scenes, scene_name)
    setattr(jaxmps.scenes, scene_name, _member_case(build, member))
    try:
        r = acc.run_case(case, method, spacing, args)
    finally:
        setattr(jaxmps.scenes, scene_name, build)
        acc.METHOD.update(original)
    row = dict(case=case, method=method, spacing=spacing, rtol=rtol, member=member)
    for key in MEASURES[case]:
        row[key] = r[key]
    return {
        **row,
        "run_s": r["run_s_best"],
        "steps": r["n_steps"],
        "result": r["result"],
    }


def _machine_line(m: dict) -> str:
    keys = ("cpu_model", "cpu_usable", "jax", "git_commit")
    return ", ".join(f"{k} {m[k]}" for k in keys if k in m) or json.dumps(m)


def markdown(data: dict) -> str:
    rows = data["rows"]
    out = [
        "# Pressure-solve tolerance vs accuracy, over an ensemble of perturbed "
        f"initial states ({data['backend']})",
        "",
        f"- machine: {_machine_line(data['machine'])}",
        f"- members per row: {data['members']} (member 0 unperturbed; the others' "
        f"fluid moved by N(0, {PERTURBATION:g} m), seed = member)",
        "- cases: `accuracy_vs_cost.py`'s standing wave (period against linear "
        "theory) and hydrostatic tank (pressure noise and mean bottom pressure), "
        "float64",
        "- run time: one call after compiling (a rough cost only)",
    ]
    for case in dict.fromkeys(r["case"] for r in rows):
        first, second = MEASURES[case]
        out += [
            "",
            f"## {case}",
            "",
            f"| method | spacing [m] | rtol | {LABELS[first]} per member | mean | "
            f"std | {LABELS[second]} (mean) | run [s] (mean) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        mine = [r for r in rows if r["case"] == case]
        keys = {(r["method"], r["spacing"], r["rtol"]) for r in mine}
        for method, spacing, rtol in sorted(keys, key=lambda k: (k[0], -k[1], k[2])):
            group = [
                r
                for r in mine
                if (r["method"], r["spacing"], r["rtol"]) == (method, spacing, rtol)
            ]
            values = np.array([r[first] for r in group])
            each = " / ".join(f"{100 * v:+.2f}" for v in values)
            spread = 100 * values.std(ddof=1) if len(values) > 1 else math.nan
            other = np.mean([r[second] for r in group])
            cost = np.mean([r["run_s"] for r in group])
            other = (
                f"{100 * other:.2f} %"
                if second != "final_amplitude"
                else f"{other:.3f}"
            )
            out.append(
                f"| {method} | {spacing:g} | {rtol:g} | {each} % | "
                f"{100 * values.mean():+.2f} % | {spread:.2f} % | {other} | "
                f"{cost:.1f} |"
            )
    return "\n".join(out) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--cases", nargs="+", choices=sorted(SCENES), default=["standing_wave"]
    )
    p.add_argument(
        "--methods",
        nargs="+",
        choices=["semi_implicit", "high_accuracy"],
        default=["semi_implicit"],
    )
    p.add_argument("--spacings", nargs="+", type=float, default=[0.01, 0.005])
    p.add_argument("--rtols", nargs="+", type=float, default=[1e-9, 1e-7, 1e-6])
    p.add_argument("--members", type=int, default=4)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--merge", action="store_true", help="add to the rows at --out")
    a = p.parse_args(argv)
    backend = jax.default_backend()
    out = a.out or HERE / "results" / f"solve_tolerance_{backend}"
    rows = []
    if a.merge and out.with_suffix(".json").exists():
        rows = json.loads(out.with_suffix(".json").read_text())["rows"]
    for case in a.cases:
        for method in a.methods:
            for spacing in a.spacings:
                for rtol in a.rtols:
                    for member in range(a.members):
                        rows.append(run(case, method, spacing, rtol, member))
                        print(json.dumps(rows[-1]), flush=True)
    data = dict(
        backend=backend,
        machine=machine_info(),
        members=a.members,
        perturbation_m=PERTURBATION,
        rows=rows,
    )
    out.with_suffix(".json").write_text(json.dumps(data, indent=1, default=str))
    out.with_suffix(".md").write_text(markdown(data))
    print(markdown(data))


if __name__ == "__main__":
    main()
