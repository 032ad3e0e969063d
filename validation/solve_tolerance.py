"""Does the pressure solve's tolerance move the standing wave's period? An ensemble.

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


def _member_case(member: int):
    """`scenes.standing_wave` with its fluid moved by PERTURBATION (member > 0)."""
    build = jaxmps.scenes.standing_wave

    def case(**config):
        out = build(**config)
        if member == 0:
            return out
        rng = np.random.default_rng(member)
        fluid = np.asarray(out.state.kind == int(jaxmps.Kind.FLUID))[:, None]
        offset = rng.normal(0.0, PERTURBATION, out.state.position.shape) * fluid
        return eqx.tree_at(lambda c: c.state.position, out, out.state.position + offset)

    return case


def run(spacing: float, rtol: float, member: int) -> dict:
    args = argparse.Namespace(repeats=1, max_timed_s=0.0)
    acc.METHOD["semi_implicit"] = dict(solver="semi_implicit", rtol=rtol)
    original = jaxmps.scenes.standing_wave
    jaxmps.scenes.standing_wave = _member_case(member)
    try:
        r = acc.run_case("standing_wave", "semi_implicit", spacing, args)
    finally:
        jaxmps.scenes.standing_wave = original
    return dict(
        spacing=spacing,
        rtol=rtol,
        member=member,
        rel_period=r["rel_period"],
        final_amplitude=r["final_amplitude"],
        run_s=r["run_s_best"],
        steps=r["n_steps"],
        result=r["result"],
    )


def _machine_line(m: dict) -> str:
    keys = ("cpu_model", "cpu_usable", "jax", "git_commit")
    return ", ".join(f"{k} {m[k]}" for k in keys if k in m) or json.dumps(m)


def markdown(data: dict) -> str:
    rows = data["rows"]
    out = [
        "# Pressure-solve tolerance vs the standing wave's period (ensemble), "
        f"{data['backend']}",
        "",
        f"- machine: {_machine_line(data['machine'])}",
        f"- members per (spacing, rtol): {data['members']} (member 0 unperturbed; "
        f"the others' fluid moved by N(0, {PERTURBATION:g} m), seed = member)",
        "- case: `accuracy_vs_cost.py`'s standing wave, standard semi-implicit, "
        "float64; period error against linear theory",
        "- run time: one call after compiling, taken while other work shared the "
        "CPU (a rough cost only)",
        "",
        "| spacing [m] | rtol | period error per member | mean | std | "
        "amplitude at the end / A (mean) | run [s] (mean) |",
        "|---|---|---|---|---|---|---|",
    ]
    keys = sorted(
        {(r["spacing"], r["rtol"]) for r in rows}, key=lambda k: (-k[0], k[1])
    )
    for spacing, rtol in keys:
        group = [r for r in rows if (r["spacing"], r["rtol"]) == (spacing, rtol)]
        errors = np.array([r["rel_period"] for r in group])
        each = " / ".join(f"{100 * e:+.2f}" for e in errors)
        amp = np.mean([r["final_amplitude"] for r in group])
        cost = np.mean([r["run_s"] for r in group])
        out.append(
            f"| {spacing:g} | {rtol:g} | {each} % | {100 * errors.mean():+.2f} % | "
            f"{100 * errors.std(ddof=1):.2f} % | {amp:.3f} | {cost:.1f} |"
        )
    return "\n".join(out) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spacings", nargs="+", type=float, default=[0.01, 0.005])
    p.add_argument("--rtols", nargs="+", type=float, default=[1e-9, 1e-7, 1e-6])
    p.add_argument("--members", type=int, default=4)
    p.add_argument("--out", type=Path, default=None)
    a = p.parse_args(argv)
    backend = jax.default_backend()
    out = a.out or HERE / "results" / f"solve_tolerance_{backend}"
    rows = []
    for spacing in a.spacings:
        for rtol in a.rtols:
            for member in range(a.members):
                rows.append(run(spacing, rtol, member))
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
