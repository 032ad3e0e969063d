r"""The sloped tank of Tomita (2016) (seed 001 §3.3.2): a frequency sweep as one
vmapped batch against the measured maxima of seed 001's Table 4.

`sloshing_tank(slope=1.5)`: a vertical left wall, 0.3 m bottom, a 1 : 1.5 slope,
0.5 m deep, shaken with A = 7.5 mm after 2 s at rest, 20 s in all (as the seed),
at f = 0.5-1.3 Hz in steps of 0.1 plus 0.64 and 1.02 Hz. Per member: the largest
run-up R on the slope (`run_up`) and side-wall height H (`eta_left`) while
shaking. The first resonance is the frequency of the largest R (and H); the
seed's criterion is agreement within the 0.1 Hz sweep step.

    python validation/tomita_sweep.py --spacing 0.02 --slope-wall staircase
    python validation/tomita_sweep.py --spacing 0.02 --slope-wall type2

writes results/tomita_sweep_<slope wall>_<l0 in mm>mm_cpu.{json,md}
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
# Seed 001 Table 4 (Tomita 2016, A = 7.5 mm, no plates): frequency [Hz], run-up
# maximum R [m], side-wall maximum H [m].
TABLE4 = (
    (0.5, 0.010, 0.004),
    (0.6, 0.049, 0.024),
    (0.64, 0.295, 0.148),
    (0.7, 0.084, 0.042),
    (0.8, 0.052, 0.010),
    (0.9, 0.038, 0.006),
    (1.0, 0.075, 0.032),
    (1.02, 0.249, 0.073),
    (1.1, 0.069, 0.046),
    (1.2, 0.017, 0.016),
    (1.3, 0.042, 0.019),
)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacing", type=float, default=0.02)
    p.add_argument("--slope-wall", default="staircase")
    p.add_argument("--scheme", default="standard")
    p.add_argument("--t-end", type=float, default=20.0)
    p.add_argument("--porous-kappa", type=float, default=None)
    p.add_argument(
        "--frequencies",
        type=float,
        nargs="+",
        default=None,
        help="other forcing frequencies [Hz] (default: Table 4's); the results "
        "name gains '_fine' (or `--tag`)",
    )
    p.add_argument("--tag", default=None, help="suffix of the results name")
    args = p.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    settings = dict(
        slope=1.5,
        spacing=args.spacing,
        slope_wall=args.slope_wall,
        scheme=args.scheme,
        settle=2.0,
    )
    if args.porous_kappa is not None:
        settings.update(
            porous_kappa=args.porous_kappa,
            porous_box="-1,0.38,0.3,0.46",
            porous_direction="vertical",
        )
    case = jaxmps.scenes.sloshing_tank(**settings)
    freqs = np.array(
        [row[0] for row in TABLE4] if args.frequencies is None else args.frequencies
    )
    # Table 4's maxima at the frequencies it has (None elsewhere).
    table = {row[0]: row[1:] for row in TABLE4}
    measured = [table.get(round(float(f), 4), (None, None)) for f in freqs]
    times = np.arange(0.05, args.t_end + 1e-9, 0.05)
    start = time.perf_counter()
    out = jaxmps.sweep(case, {"motion.frequency": freqs}, times=times)
    wall = time.perf_counter() - start
    name = f"tomita_sweep_{args.slope_wall}_{round(1000 * args.spacing)}mm"
    if args.porous_kappa is not None:
        name += f"_kappa{args.porous_kappa:g}"
    if args.tag is not None:
        name += f"_{args.tag}"
    elif args.frequencies is not None:
        name += "_fine"
    out.save(HERE / "results" / f"{name}_cpu.h5")  # every series, before any summary
    t = np.asarray(out.saved["time"])[0]
    shaking = t > 2.0
    run_up = np.asarray(out.saved["run_up"])[:, shaking].max(axis=1)
    height = np.asarray(out.saved["eta_left"])[:, shaking].max(axis=1)
    results = out.messages()
    record = dict(
        settings=settings,
        particles=int(case.state.active.sum()),
        wall_s=wall,
        freqs=freqs.tolist(),
        run_up=run_up.tolist(),
        side_wall=height.tolist(),
        measured_run_up=[m[0] for m in measured],
        measured_side_wall=[m[1] for m in measured],
        results=results,
        machine=machine_info(),
    )
    # The largest response below and above 0.85 Hz (None where no frequency).
    for label, band in (("first", freqs < 0.85), ("second", freqs > 0.85)):
        for probe, values in (("R", run_up), ("H", height)):
            record[f"{label}_resonance_{probe}"] = (
                float(freqs[band][np.argmax(values[band])]) if band.any() else None
            )
    (HERE / "results" / f"{name}_cpu.json").write_text(json.dumps(record, indent=1))
    lines = [
        f"# Tomita sloped tank sweep: slope wall {args.slope_wall}, "
        f"l0 = {args.spacing} m, {args.scheme} (float64, CPU)",
        "",
        f"{record['particles']} particles, {len(freqs)} members in one vmapped "
        f"batch, {args.t_end:g} s each, wall {wall:.0f} s. A = 7.5 mm after 2 s.",
        "Measured: seed 001 Table 4 (Tomita 2016).",
        "",
        "| f [Hz] | R [m] | R measured | H [m] | H measured | result |",
        "|---|---|---|---|---|---|",
    ]
    for i, f in enumerate(freqs):
        r_m, h_m = ("" if m is None else f"{m:.3f}" for m in measured[i])
        lines.append(
            f"| {f:g} | {run_up[i]:.3f} | {r_m} | {height[i]:.3f} "
            f"| {h_m} | {results[i]} |"
        )
    lines += [
        "",
        f"First resonance (largest below 0.85 Hz): R at "
        f"{record['first_resonance_R']} Hz, H at {record['first_resonance_H']} "
        "Hz (measured 0.64 Hz); second (above): R at "
        f"{record['second_resonance_R']} Hz, H at "
        f"{record['second_resonance_H']} Hz (measured 1.02 Hz).",
        "",
        f"Machine: {record['machine']}",
    ]
    (HERE / "results" / f"{name}_cpu.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
