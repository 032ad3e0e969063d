r"""Sloshing resonance of the 0.5 m x 0.3 m tank (seed 001 §3.3.1) from one vmapped
frequency sweep, against linear theory (1.2204 / 2.1631 Hz).

Each member shakes the tank with A = 2 mm after `--settle` s at rest, for `--shake`
s; the response is the largest |mode amplitude| / A of the excited surface mode
(probe `mode1`: cos(pi x / L); `mode2`: cos(3 pi x / L)). The resonance is the
frequency of the largest response, refined by a parabola through it and its two
neighbours.

    python validation/resonance_sweep.py --spacing 0.025 \
        --freqs 1.10 1.16 1.22 1.28 1.34 2.04 2.10 2.16 2.22 2.28
    python validation/resonance_sweep.py --spacing 0.0125 \
        --freqs 1.16 1.20 1.24 1.28 1.32

Prints the responses and the peaks; `--out FILE.json` saves them.
"""

import argparse
import json
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
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
    p.add_argument("--freqs", type=float, nargs="+", required=True)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    case = jaxmps.scenes.sloshing_tank(
        spacing=args.spacing, settle=args.settle, scheme=args.scheme
    )
    freqs = np.asarray(args.freqs)
    dt = float(case.params.dt)
    n = int((args.settle + args.shake) / dt) // 10 * 10
    t0 = time.perf_counter()
    out = jaxmps.sweep(case, {"motion.frequency": freqs}, n, 10)
    wall = time.perf_counter() - t0
    t = np.asarray(out.saved["time"])[0]
    after = t > args.settle
    amp = case.config["amplitude"]
    record = dict(
        spacing=args.spacing,
        scheme=args.scheme,
        particles=int(case.state.active.sum()),
        dt=dt,
        steps=n,
        wall_s=wall,
        freqs=freqs.tolist(),
        theory=case.config["resonances"],
        results=np.asarray(out.result).tolist(),
    )
    for m, (lo, hi) in (("mode1", (0, 1.7)), ("mode2", (1.7, 9))):
        r = np.abs(np.asarray(out.saved[m]))[:, after].max(axis=1) / amp
        record[m] = r.tolist()
        band = (freqs > lo) & (freqs < hi)
        if band.sum() >= 3:
            record[f"{m}_peak"] = peak(freqs[band], r[band])
    print(json.dumps(record, indent=1))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
