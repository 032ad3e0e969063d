r"""Sloshing resonance of a rectangular tank (default the 0.5 m x 0.3 m of seed 001
§3.3.1) from one vmapped frequency sweep, against linear theory (1.2204 / 2.1631 Hz
for the default tank; `--tank-length`, `--depth` for others).

Each member shakes the tank with A = 2 mm after `--settle` s at rest, for `--shake`
s; the response is the largest |mode amplitude| / A of the excited surface mode
(probe `mode1`: cos(pi x / L); `mode2`: cos(3 pi x / L)). The resonance is the
frequency of the largest response, refined by a parabola through it and its two
neighbours.

    python validation/resonance_sweep.py --spacing 0.025 \
        --freqs 1.10 1.16 1.22 1.28 1.34 2.04 2.10 2.16 2.22 2.28
    python validation/resonance_sweep.py --spacing 0.0125 \
        --freqs 1.16 1.20 1.24 1.28 1.32
    python validation/resonance_sweep.py --spacing 0.0125 --tank-length 0.8 \
        --depth 0.16 --around 0.92 0.96 1.0 1.04 1.08

`--around` gives the frequencies as multiples of the tank's linear first
resonance instead of `--freqs`.

Prints the responses and the peaks; `--out FILE.json` saves them.
"""

import argparse
import json

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
from _common import shaken_sweep  # noqa: E402

import jaxmps  # noqa: E402


def peak(freqs, response):
    i = int(np.clip(np.argmax(response), 1, len(freqs) - 2))
    a, b, c = response[i - 1 : i + 2]
    h = freqs[i + 1] - freqs[i]
    return float(freqs[i] + 0.5 * h * (a - c) / (a - 2 * b + c))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacing", type=float, default=0.025)
    p.add_argument("--scheme", default="standard")
    p.add_argument("--settle", type=float, default=0.5)
    p.add_argument("--shake", type=float, default=8.0)
    p.add_argument("--tank-length", type=float, default=None, help="m (0.5)")
    p.add_argument("--depth", type=float, default=None, help="water depth, m (0.3)")
    p.add_argument("--tank-height", type=float, default=None, help="m (0.6)")
    p.add_argument("--amplitude", type=float, default=None, help="m (2e-3)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--freqs", type=float, nargs="+")
    which.add_argument("--around", type=float, nargs="+", help="multiples of f1")
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    geometry = {
        k: v
        for k, v in (
            ("tank_length", args.tank_length),
            ("depth", args.depth),
            ("tank_height", args.tank_height),
            ("amplitude", args.amplitude),
        )
        if v is not None
    }
    case = jaxmps.scenes.sloshing_tank(
        spacing=args.spacing, settle=args.settle, scheme=args.scheme, **geometry
    )
    f1 = case.config["resonances"][0]
    freqs = np.asarray(args.freqs or [round(a * f1, 4) for a in args.around])
    dt = float(case.params.dt)
    out, n, wall, _, after = shaken_sweep(case, freqs, args.settle, args.shake)
    amp = case.config["amplitude"]
    record = dict(
        spacing=args.spacing,
        scheme=args.scheme,
        tank_length=case.config["tank_length"],
        depth=case.config["depth"],
        amplitude=case.config["amplitude"],
        shake=args.shake,
        particles=int(case.state.active.sum()),
        dt=dt,
        steps=n,
        wall_s=wall,
        freqs=freqs.tolist(),
        theory=case.config["resonances"],
        results=np.asarray(out.result).tolist(),
    )
    f2 = case.config["resonances"][1]
    split = 0.5 * (f1 + f2)
    for m, (lo, hi) in (("mode1", (0, split)), ("mode2", (split, 99))):
        r = np.abs(np.asarray(out.saved[m]))[:, after].max(axis=1) / amp
        record[m] = r.tolist()
        band = (freqs > lo) & (freqs < hi)
        if band.sum() >= 3:
            record[f"{m}_peak"] = peak(freqs[band], r[band])
            theory = record["theory"][0 if m == "mode1" else 1]
            record[f"{m}_error"] = record[f"{m}_peak"] / theory - 1
    print(json.dumps(record, indent=1))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
