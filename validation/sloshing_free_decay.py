r"""First sloshing mode of rectangular tanks of several depth ratios h/L, from a free
decay, against linear theory: the period and the damping of the tank's own mode,
with no forcing to mistake for it.

Each run releases the surface depth + A cos(pi x / L) from rest
(`scenes.standing_wave(mode_number=1)`) and follows the amplitude of that mode
(probe `mode`, an integral over all fluid particles) for `--periods` linear
periods. A damped cosine a + exp(-s t) (b cos w t + c sin w t) fitted to the whole
record gives the period 2 pi / w and the damping ratio s / w; the period from the
mean spacing of the zero crossings is reported beside it. Linear theory: omega^2 =
g k tanh(k h), k = pi / L; the inviscid mode does not decay, so the damping is the
scheme's (and the viscosity's, nu = 1e-6 m^2/s: 2 nu k^2 / omega ~ 1e-5 here).

    python validation/sloshing_free_decay.py                       # ~3 min, 2 cores
    python validation/sloshing_free_decay.py --ratios 0.2 --schemes standard
    python validation/sloshing_free_decay.py --schemes explicit \
        --out results/sloshing_free_decay_explicit_cpu      # E-MPS

Writes results/sloshing_free_decay_cpu.{json,md}.
"""

import argparse
import json
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
from _common import (  # noqa: E402
    HERE,
    crossing_period,
    damped_fit,
    free_decay,
    machine_info,
    result_name,
)

import jaxmps  # noqa: E402


def run(ratio, scheme, args):
    depth = round(ratio * args.tank_length / args.spacing) * args.spacing
    case = jaxmps.scenes.standing_wave(
        mode_number=1,
        tank_length=args.tank_length,
        depth=depth,
        tank_height=depth + max(0.1, 4 * args.amplitude),
        amplitude=args.amplitude,
        spacing=args.spacing,
        # "explicit": E-MPS (the explicit solver, whose scheme is the standard one)
        **(
            dict(solver="explicit", scheme="standard")
            if scheme == "explicit"
            else dict(scheme=scheme)
        ),
    )
    period = case.config["linear_period"]
    dt = float(case.params.dt)
    tr, n, wall, t, y = free_decay(case, args.periods)
    fit_period, zeta, rms = damped_fit(t, y, period)
    cross, count = crossing_period(t, y)
    probe = {q.name: q for q in case.probes}["mode"]
    a0 = float(probe(case.scene, case.state))
    row = dict(
        ratio=ratio,
        depth=case.config["depth"],
        scheme=scheme,
        particles=int(np.sum(np.asarray(case.state.kind) == 0)),
        dt=dt,
        steps=n,
        wall_s=wall,
        result=result_name(tr.result),
        initial_amplitude=a0,
        k_amplitude=np.pi / case.config["tank_length"] * a0,
        linear_period=period,
        fit_period=fit_period,
        fit_error=fit_period / period - 1,
        crossing_period=cross,
        crossing_error=cross / period - 1,
        crossings=count,
        damping_ratio=zeta,
        fit_rms_over_a0=rms / a0,
        time=t.tolist(),
        mode=y.tolist(),
    )
    print(json.dumps({k: v for k, v in row.items() if k not in ("time", "mode")}))
    return row


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ratios", type=float, nargs="+", default=[0.2, 0.4, 0.6])
    p.add_argument(
        "--schemes", nargs="+", default=["standard", "high_accuracy", "standard_ds"]
    )
    p.add_argument("--tank-length", type=float, default=0.5)
    p.add_argument("--spacing", type=float, default=0.01)
    p.add_argument("--amplitude", type=float, default=0.01)
    p.add_argument("--periods", type=float, default=4.0)
    p.add_argument(
        "--out", type=Path, default=HERE / "results" / "sloshing_free_decay_cpu"
    )
    args = p.parse_args(argv)
    rows = [run(r, s, args) for s in args.schemes for r in args.ratios]
    info = dict(
        machine=machine_info(),
        tank_length=args.tank_length,
        spacing=args.spacing,
        amplitude=args.amplitude,
        periods=args.periods,
    )
    args.out.with_suffix(".json").write_text(
        json.dumps(dict(info=info, rows=rows), indent=1)
    )
    lines = [
        "# First sloshing mode, free decay (CPU, float64)",
        "",
        f"- {info['machine']['cpu_model']}, {info['machine']['cpu_usable']} cores; "
        f"jax {info['machine']['jax']}; git {info['machine']['git_commit']}",
        "",
        f"Tank L = {args.tank_length} m, l0 = {args.spacing} m, released with "
        f"A = {args.amplitude} m of cos(pi x / L) (on the lattice: the initial "
        "amplitude below), followed for "
        f"{args.periods:g} linear periods; `validation/sloshing_free_decay.py`. "
        "Period: damped-cosine fit (and mean zero-crossing spacing); damping ratio "
        "s / w of the fit (linear inviscid theory: 0).",
        "",
        "| scheme | h/L | particles | kA | T linear [s] | T fit [s] | error | "
        "T crossings | error | damping ratio | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scheme']} | {r['ratio']:g} | {r['particles']} | "
            f"{r['k_amplitude']:.3f} | {r['linear_period']:.4f} | "
            f"{r['fit_period']:.4f} | {100 * r['fit_error']:+.2f} % | "
            f"{r['crossing_period']:.4f} | {100 * r['crossing_error']:+.2f} % | "
            f"{r['damping_ratio']:.4f} | {r['wall_s']:.0f} |"
        )
    args.out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
