"""Heave free decay of a floating box against linear potential-flow theory.

`scenes.floating_box` (B = 0.2 m, H = 0.1 m, density ratio 0.5, so B/T = 4;
`body_pressure="fluid"`) in a tank `--tank` m long and `--depth` m deep (long, so
that the radiated waves return from the end walls only after the decay), released
1 cm below its Archimedes draft. The centre's height is fitted over the first
`--fit` seconds with y = c + exp(-zeta w t) (a cos(w_d t) + b sin(w_d t)),
w_d = w sqrt(1 - zeta^2) (grid search over w and zeta, linear least squares for
a, b, c). Theory (`_heave_theory.py`): w_n of w^2 (m + a33(w)) = rho g B and the
radiation damping ratio b33 / (2 (m + a33) w_n) at the same depth.

Run: python validation/heave_decay.py [--spacings 0.02 0.01]
(writes results/heave_decay_cpu.{json,md})
"""

import argparse
import json
import time

import jax
import numpy as np
from _common import HERE, machine_info
from _heave_theory import free_heave

import jaxmps


def fit_decay(t, y):
    """(w [rad/s], zeta, rms residual / amplitude) of the damped oscillation."""
    best = (np.inf, None)
    for w in np.linspace(4.0, 16.0, 241):
        for zeta in np.linspace(0.0, 0.5, 101):
            wd = w * np.sqrt(1 - zeta**2)
            e = np.exp(-zeta * w * t)
            basis = np.stack(
                [np.ones_like(t), e * np.cos(wd * t), e * np.sin(wd * t)], 1
            )
            coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
            r = np.sum((basis @ coef - y) ** 2)
            if r < best[0]:
                best = (r, (w, zeta, coef))
    r, (w, zeta, coef) = best
    amplitude = np.hypot(coef[1], coef[2])
    return w, zeta, np.sqrt(r / len(t)) / amplitude


def measure(spacing, tank, depth, offset, t_end, fit):
    case = jaxmps.scenes.floating_box(
        spacing=spacing,
        tank_length=tank,
        depth=depth,
        initial_draft=0.05 + offset,
        body_pressure="fluid",
        t_end=t_end,
    )
    dt = float(case.params.dt)
    saves = round(t_end / 0.01)
    every = max(1, round(t_end / dt) // saves)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        every * saves,
        every,
        observe=jaxmps.scenes.observe_probes(case.probes),
    )
    wall = time.perf_counter() - start
    s = {k: np.asarray(v) for k, v in out.saved.items()}
    t, y = s["time"], s["box_y"]
    window = t <= fit
    w, zeta, residual = fit_decay(t[window], y[window])
    c = case.config
    w_th, zeta_th, added = free_heave(c["box_width"], 0.05, c["depth"])
    return dict(
        spacing=spacing,
        tank=tank,
        depth=c["depth"],
        particles=int(case.state.active.sum()),
        period=2 * np.pi / w,
        zeta=zeta,
        fit_residual=residual,
        period_theory=2 * np.pi / w_th,
        zeta_theory=zeta_th,
        added_mass_over_mass=added,
        period_error=(w_th / w) - 1,
        wall_s=wall,
        result=str(out.result),
        series=dict(time=t.tolist(), box_y=y.tolist()),
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacings", nargs="+", type=float, default=[0.02, 0.01])
    parser.add_argument("--tank", type=float, default=3.0)
    parser.add_argument("--depth", type=float, default=0.4)
    parser.add_argument("--offset", type=float, default=0.01)
    parser.add_argument("--t-end", type=float, default=3.0)
    parser.add_argument("--fit", type=float, default=2.5)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    rows = []
    for l0 in args.spacings:
        row = measure(l0, args.tank, args.depth, args.offset, args.t_end, args.fit)
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "series"}), flush=True)
    info = machine_info()
    path = HERE / "results" / "heave_decay_cpu"
    path.with_suffix(".json").write_text(
        json.dumps({"machine": info, "args": vars(args), "rows": rows}, indent=1)
    )
    lines = [
        "# Heave free decay of a floating box against potential-flow theory",
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; `validation/heave_decay.py`"
        f" (tank {args.tank} m, depth {args.depth} m, released {args.offset} m below",
        f"the Archimedes draft, fit over the first {args.fit} s).",
        "",
        "| l0 [m] | particles | period [s] | theory [s] | error | zeta |"
        " zeta, radiation only | fit residual | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['spacing']} | {r['particles']} | {r['period']:.4f} |"
            f" {r['period_theory']:.4f} | {r['period'] / r['period_theory'] - 1:+.1%} |"
            f" {r['zeta']:.3f} | {r['zeta_theory']:.3f} | {r['fit_residual']:.2f} |"
            f" {r['wall_s']:.0f} |"
        )
    path.with_suffix(".md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
