"""Elastic cantilever against Euler-Bernoulli, and the elastic step's stability map.

1. Convergence: `scenes.elastic_cantilever` (0.2 x 0.02 m, E = 1e7 Pa, nu = 0.3,
   rho = 1000 kg/m^3, clamped by three layers) released from rest under gravity
   at 4, 8 and 16 particles through the thickness. Undamped, the tip oscillates
   about its static deflection with the first mode's period: the mean over whole
   periods (between the first and last upward crossings of the run's mean) is the
   static deflection, the crossings' spacing the period. Both against
   Euler-Bernoulli (`scenes.cantilever_theory`; plane strain in 2-D).
2. Stability map: the 8-layer beam (E = 1e6 Pa, g = 0.981) with dt = 1 ms split
   into fewer and fewer sub-steps (`add_elastic_bodies(substeps=...)`, the limit
   check lifted), for nu = 0, 0.3, 0.48: whether 0.15 s runs without a failure and
   stays bounded, in units of h c_s / l0 and h c_p / l0.

Run: python validation/elastic_cantilever.py [--layers 4 8 16] [--map]
(writes results/elastic_cantilever_cpu.{json,md}).
"""

import argparse
import dataclasses
import json
import time

import jax
import numpy as np
from _common import HERE, machine_info

import jaxmps


def rollout(case, t_end, every=0.002):
    """The tip's vertical displacement every `every` seconds, the wall time [s]
    and the run's result."""
    times = np.arange(1, int(round(t_end / every)) + 1) * every
    observe = jaxmps.scenes.observe_probes(case.probes)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene, case.params, case.state, times=times, observe=observe, throw=False
    )
    wall = time.perf_counter() - start
    axis = "tip_y" if case.scene.dim == 2 else "tip_z"
    return times, np.asarray(out.saved[axis]), wall, out.result


def period_and_mean(times, y):
    """The oscillation's period (mean spacing of upward crossings of the mean, by
    linear interpolation) and its mean over the whole periods between them."""
    level = y.mean()
    up = np.nonzero((y[:-1] < level) & (y[1:] >= level))[0]
    crossing = times[up] + (level - y[up]) / (y[up + 1] - y[up]) * (times[1] - times[0])
    inside = (times >= crossing[0]) & (times < crossing[-1])
    return float(np.diff(crossing).mean()), float(y[inside].mean()), len(crossing)


def convergence_row(layers, periods):
    case = jaxmps.scenes.elastic_cantilever(spacing=0.02 / layers)
    theory = jaxmps.scenes.cantilever_theory(case.config)
    times, y, wall, result = rollout(case, periods * theory["period"])
    period, mean, crossings = period_and_mean(times, y)
    return dict(
        layers=layers,
        spacing=case.config["spacing"],
        particles=int(case.state.active.sum()),
        substeps=case.scene.elastic.substeps,
        dt_max=float(case.params.dt),
        period=period,
        period_theory=theory["period"],
        period_error=period / theory["period"] - 1,
        deflection=-mean,
        deflection_theory=theory["deflection"],
        deflection_error=-mean / theory["deflection"] - 1,
        crossings=crossings,
        wall_s=wall,
        result=str(result),
    )


def stability_row(nu, substeps, t_end=0.15):
    """The 8-layer beam at E = 1e6 Pa, g = 0.981, dt = 1 ms in `substeps`."""
    overrides = dict(
        youngs_modulus=1e6, poisson_ratio=nu, gravity=0.981, spacing=0.0025, dt=1e-3
    )
    case = jaxmps.scenes.elastic_cantilever(**overrides)
    model = case.scene.elastic
    lifted = jaxmps.bodies.ElasticBodies(
        count=model.count, spacing=model.spacing, substeps=substeps, courant=100.0
    )
    case = dataclasses.replace(
        case, scene=dataclasses.replace(case.scene, elastic=lifted)
    )
    times, y, _, result = rollout(case, t_end, every=0.005)
    lam, mu = (float(v) for v in jaxmps.bodies.lame(1e6, nu))
    h = 1e-3 / substeps
    stable = bool(
        result == jaxmps.Result.successful
        and np.all(np.isfinite(y))
        and np.abs(y).max() < 0.02
    )
    return dict(
        poisson_ratio=nu,
        substeps=substeps,
        h_cs_l0=h * np.sqrt(mu / 1000.0) / 0.0025,
        h_cp_l0=h * np.sqrt((lam + 2 * mu) / 1000.0) / 0.0025,
        stable=stable,
        result=str(result),
    )


def markdown(rows, stability, info):
    lines = [
        "# Elastic cantilever against Euler-Bernoulli",
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; "
        "`validation/elastic_cantilever.py`.",
        "0.2 x 0.02 m beam, E = 1e7 Pa, nu = 0.3, rho = 1000 kg/m^3, g = 9.81, "
        "released from rest; theory: plane strain, E' = E / (1 - nu^2).",
        "",
        "| layers | l0 [mm] | particles | substeps | period [s] | theory [s] | error |"
        " static tip [mm] | theory [mm] | error | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['layers']} | {1e3 * r['spacing']:.3g} | {r['particles']} |"
            f" {r['substeps']} | {r['period']:.4f} | {r['period_theory']:.4f} |"
            f" {100 * r['period_error']:+.1f} % | {1e3 * r['deflection']:.3f} |"
            f" {1e3 * r['deflection_theory']:.3f} |"
            f" {100 * r['deflection_error']:+.1f} % | {r['wall_s']:.0f} |"
        )
    if stability:
        lines += [
            "",
            "## Stability map (8 layers, E = 1e6 Pa, dt = 1 ms in sub-steps h)",
            "",
            "| nu | substeps | h c_s / l0 | h c_p / l0 | stable |",
            "|---|---|---|---|---|",
        ]
        for r in stability:
            lines.append(
                f"| {r['poisson_ratio']} | {r['substeps']} | {r['h_cs_l0']:.3f} |"
                f" {r['h_cp_l0']:.3f} | {'yes' if r['stable'] else 'no'} |"
            )
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layers", nargs="*", type=int, default=[4, 8, 16])
    parser.add_argument("--periods", type=float, default=3.2)
    parser.add_argument("--map", action="store_true", help="run the stability map")
    parser.add_argument("--out", default="elastic_cantilever_cpu")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / args.out
    rows, stability = [], []
    if path.with_suffix(".json").exists():
        old = json.loads(path.with_suffix(".json").read_text())
        rows = [r for r in old["rows"] if r["layers"] not in args.layers]
        stability = [] if args.map else old.get("stability", [])
    info = machine_info()

    def write():
        rows.sort(key=lambda r: r["layers"])
        data = {"machine": info, "rows": rows, "stability": stability}
        path.with_suffix(".json").write_text(json.dumps(data, indent=1))
        path.with_suffix(".md").write_text(markdown(rows, stability, info))

    for layers in args.layers:
        rows.append(convergence_row(layers, args.periods))
        print(json.dumps(rows[-1]), flush=True)
        write()
    if args.map:
        for nu, counts in (
            (0.0, (30, 25, 20, 16)),
            (0.3, (25, 20, 17, 15)),
            (0.48, (30, 25, 20, 16)),
        ):
            for substeps in counts:
                stability.append(stability_row(nu, substeps))
                print(json.dumps(stability[-1]), flush=True)
                write()


if __name__ == "__main__":
    main()
