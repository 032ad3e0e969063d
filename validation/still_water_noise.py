"""Still-water pressure noise of the `standard` and `high_accuracy` presets at their
default settings, over tanks of several sizes and resolutions.

`hydrostatic` tanks (width x depth: 0.2 x 0.2, 0.5 x 0.3, 1.0 x 0.5 m; 0.3 x
0.15 m; l0 = 1 and 2 cm), adaptive steps (the default), 2 s from rest. At the
bottom probe (`pressure_bottom`, the fluid within 1.5 l0 of the bottom centre):
the mean over 0.5-2 s against rho g (H - y_p) (`scenes.hydrostatic_pressure`),
and the noise: the standard deviation over 0.5-2 s, both relative to that value.
The high-accuracy scheme must be no noisier than `standard` in any tank; the
`standard_ds` column is the standard scheme with the unshifted gradient and
dynamic stabilisation (`schemes.standard(dynamic_stabilisation=True)`).

Run: python validation/still_water_noise.py [--spacings 0.02] [--dt-max 5e-4
[--relaxation-step calm] --out still_water_noise_dt_0.5ms_cpu]  (writes
results/still_water_noise_cpu.{json,md} or the --out name)
"""

import argparse
import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
TANKS = ((0.2, 0.2), (0.3, 0.15), (0.5, 0.3), (1.0, 0.5))
SPACINGS = (0.02, 0.01)
SCHEMES = ("standard", "high_accuracy", "standard_ds")


def run(width, depth, spacing, scheme, t_end=2.0, dt_max=None, relaxation=None):
    case = jaxmps.scenes.hydrostatic(
        width=width,
        depth=depth,
        spacing=spacing,
        scheme=scheme,
        dt_max=dt_max,
        relaxation_step=relaxation,
    )
    probe = {p.name: p for p in case.probes}["pressure_bottom"]
    reference = jaxmps.scenes.hydrostatic_pressure(case)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=np.arange(0.01, t_end + 1e-9, 0.01),
        observe=jaxmps.scenes.observe_probes((probe,)),
        throw=False,
    )
    wall = time.perf_counter() - start
    t = np.asarray(out.saved["time"])
    p = np.asarray(out.saved["pressure_bottom"])[t >= 0.5]
    return dict(
        width=width,
        depth=depth,
        spacing=spacing,
        scheme=scheme,
        dt_max=float(case.params.dt),
        particles=int(case.state.active.sum()),
        mean_error=float(p.mean() / reference - 1),
        noise=float(p.std() / reference),
        steps=int(np.asarray(out.steps.accepted).sum()),
        result="ok" if out.result == jaxmps.Result.successful else str(out.result),
        wall_s=wall,
    )


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacings", type=float, nargs="+", default=list(SPACINGS))
    p.add_argument(
        "--dt-max",
        type=float,
        default=None,
        help="the adaptive step's upper bound [s] (default: the scene's)",
    )
    p.add_argument(
        "--relaxation-step",
        default=None,
        help="the scenes' relaxation_step ('calm' or seconds; default: per step)",
    )
    p.add_argument("--out", default="still_water_noise_cpu", help="results name")
    args = p.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    rows = []
    for width, depth in TANKS:
        for spacing in args.spacings:
            if width / spacing > 60 and spacing < 0.02:
                continue  # the 1 m tank at 1 cm: 5000 particles, left to a GPU
            for scheme in SCHEMES:
                relax = args.relaxation_step
                relax = relax if relax in (None, "calm") else float(relax)
                rows.append(
                    run(
                        width,
                        depth,
                        spacing,
                        scheme,
                        dt_max=args.dt_max,
                        relaxation=relax,
                    )
                )
                print(rows[-1], flush=True)
    out = dict(machine=machine_info(), rows=rows)
    (HERE / "results" / f"{args.out}.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Still-water bottom pressure: standard, high_accuracy and standard_ds "
        "(float64, CPU)",
        "",
        "Default settings (adaptive steps), 2 s from rest, statistics over 0.5-2 s,",
        "relative to rho g (H - y_p). Largest step: "
        + ("the scene's" if args.dt_max is None else f"dt_max = {args.dt_max} s")
        + " (the step taken in still water); the density relaxed "
        + (
            "per step"
            if args.relaxation_step is None
            else f"per relaxation_step={args.relaxation_step!r}"
        )
        + ".",
        "",
        "| tank W x H [m] | l0 [m] | particles | standard mean / noise "
        "| high_accuracy mean / noise | standard_ds mean / noise "
        "| HA noise / standard | HA noise / standard_ds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    k = len(SCHEMES)
    for i in range(0, len(rows), k):
        s, h, d = rows[i : i + k]
        lines.append(
            f"| {s['width']} x {s['depth']} | {s['spacing']} | {s['particles']} "
            + "".join(
                f"| {100 * r['mean_error']:+.2f} % / {100 * r['noise']:.2f} % "
                for r in (s, h, d)
            )
            + f"| {h['noise'] / s['noise']:.2f} | {h['noise'] / d['noise']:.2f} |"
        )
    lines += ["", f"Machine: {out['machine']}"]
    (HERE / "results" / f"{args.out}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
