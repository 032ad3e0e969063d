r"""Submerged horizontal plates at the side walls of a shaken tank (seed 001 §4.2,
after Urata 2009): the resonance curves of the 0.45 m x 0.25 m tank without
plates and with plates 100 mm and 25 mm below the surface, and the first mode's
free decay in each.

Forced: for each configuration one vmapped batch over the frequencies shakes the
tank with A = 2 mm after `--settle` s at rest, for `--shake` s; the responses are
the largest |eta_left| / A (the strip level over the 3 l0 next to the left wall,
the seed's wall wave height) and the largest |mode1| / A (the amplitude of the
cos(pi x / L) surface mode) while shaking. The resonance is the frequency of the
largest mode-1 response, refined by a parabola through it and its neighbours.

Free decay: the surface depth + a cos(pi x / L) released from rest
(`scenes.standing_wave(mode_number=1)`), its mode amplitude fitted with a damped
cosine over `--periods` linear periods: the period and damping ratio the plates
give the tank's first mode.

Linear theory without plates: f1 = 1.2769 Hz (seed 001 eq. 3.7). Plate length
(not given by Urata's text): `--plate-length`, 0.1 m by default. Each plate is
three particle layers thick, its middle layer on the lattice row nearest the
installation depth (as seed 001 sets its dummy layer there).

    python validation/urata_plates.py --spacing 0.01              # ~40 min, 2 cores
    python validation/urata_plates.py --spacing 0.005 --plates 0.025 \
        --freqs 1.0 1.2 1.4 --out results/urata_plates_5mm_cpu

Writes results/urata_plates_cpu.{json,md} (or `--out`).
"""

import argparse
import json
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
from _common import (  # noqa: E402
    HERE,
    damped_fit,
    free_decay,
    machine_info,
    result_name,
    shaken_sweep,
)

import jaxmps  # noqa: E402

TANK = dict(tank_length=0.45, depth=0.25, tank_height=0.45)
SEED_FREQUENCIES = [round(0.8 + 0.05 * i, 2) for i in range(15)] + [1.276909]


def peak(freqs, response):
    """The largest response's frequency, refined by the vertex of the parabola
    through it and its two neighbours; NaN when it lies at the band's edge."""
    order = np.argsort(freqs)
    f, r = np.asarray(freqs)[order], np.asarray(response)[order]
    i = int(np.argmax(r))
    if i in (0, len(f) - 1):
        return float("nan")
    a, b, _ = np.polyfit(f[i - 1 : i + 2], r[i - 1 : i + 2], 2)
    return float(-b / (2 * a)) if a < 0 else float(f[i])


def plate_settings(plate, args):
    if plate is None:
        return {}
    return dict(plate_depth=plate, plate_length=args.plate_length)


def forced(plate, args):
    case = jaxmps.scenes.sloshing_tank(
        spacing=args.spacing,
        settle=args.settle,
        scheme=args.scheme,
        amplitude=args.amplitude,
        **TANK,
        **plate_settings(plate, args),
    )
    freqs = np.asarray(args.freqs)
    out, n, wall, _, shaking = shaken_sweep(case, freqs, args.settle, args.shake)
    amp = args.amplitude
    response = {
        name: (np.abs(np.asarray(out.saved[name]))[:, shaking].max(axis=1) / amp)
        for name in ("eta_left", "mode1")
    }
    return dict(
        particles=int(case.state.active.sum()),
        fluid=int(np.sum(np.asarray(case.state.kind) == 0)),
        plate_centre_depth=case.config["plate_centre_depth"],
        dt=float(case.params.dt),
        steps=n,
        forced_wall_s=wall,
        results=out.messages(),
        freqs=freqs.tolist(),
        eta_left=response["eta_left"].tolist(),
        mode1=response["mode1"].tolist(),
        peak_mode1=peak(freqs, response["mode1"]),
        peak_eta_left=peak(freqs, response["eta_left"]),
    )


def free(plate, args):
    case = jaxmps.scenes.standing_wave(
        mode_number=1,
        amplitude=args.release,
        spacing=args.spacing,
        scheme=args.scheme,
        **{**TANK, "tank_height": 0.35},
        **plate_settings(plate, args),
    )
    period = case.config["linear_period"]
    tr, _, wall, t, y = free_decay(case, args.periods)
    fit_period, zeta, rms = damped_fit(t, y, period)
    return dict(
        free_wall_s=wall,
        free_result=result_name(tr.result),
        linear_period=period,
        free_period=fit_period,
        free_frequency=1 / fit_period,
        free_damping_ratio=zeta,
        free_fit_rms=rms / args.release,
        free_time=t.tolist(),
        free_mode=y.tolist(),
    )


def markdown(info, rows):
    lines = [
        "# Submerged plates in the Urata tank (CPU, float64)",
        "",
        f"0.45 m x 0.25 m water, {info['scheme']} scheme, l0 = "
        f"{info['spacing'] * 1e3:g} mm, plates {info['plate_length']} m long at both "
        f"side walls, three layers thick; A = {info['amplitude'] * 1e3:g} mm, "
        f"{info['settle']} s at rest, {info['shake']} s shaking; free decay "
        f"released at {info['release'] * 1e3:g} mm over {info['periods']} linear "
        "periods (`validation/urata_plates.py`). Linear theory without plates: "
        "f1 = 1.2769 Hz.",
        "",
        f"Host: {info['machine']['cpu_model']}, {info['machine']['cpu_usable']} "
        f"cores, JAX {info['machine']['jax']}, {info['machine']['date'][:10]}; "
        "resonance NaN: the largest response at the band's edge.",
        "",
        "| plates | middle layer depth [mm] | particles | dt [ms] | forced wall [s] "
        "| resonance by mode 1 [Hz] | by eta_left [Hz] | free-decay f [Hz] "
        "| damping ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        depth = r["plate_centre_depth"]
        lines.append(
            f"| {_label(r)} | {'' if depth is None else f'{depth * 1e3:.1f}'} "
            f"| {r['particles']} "
            f"| {r['dt'] * 1e3:.3f} | {r['forced_wall_s']:.0f} "
            f"| {r['peak_mode1']:.3f} | {r['peak_eta_left']:.3f} "
            f"| {r.get('free_frequency', float('nan')):.3f} "
            f"| {r.get('free_damping_ratio', float('nan')):.3f} |"
        )
    lines += ["", "Largest |eta_left| / A while shaking:", ""]
    freqs = rows[0]["freqs"]
    lines.append("| f [Hz] | " + " | ".join(_label(r) for r in rows) + " |")
    lines.append("|---" * (len(rows) + 1) + "|")
    for i in np.argsort(freqs):
        values = " | ".join(f"{r['eta_left'][i]:.2f}" for r in rows)
        lines.append(f"| {freqs[i]:g} | {values} |")
    lines += ["", "Largest |mode1| / A while shaking:", ""]
    lines.append("| f [Hz] | " + " | ".join(_label(r) for r in rows) + " |")
    lines.append("|---" * (len(rows) + 1) + "|")
    for i in np.argsort(freqs):
        values = " | ".join(f"{r['mode1'][i]:.2f}" for r in rows)
        lines.append(f"| {freqs[i]:g} | {values} |")
    return "\n".join(lines) + "\n"


def _label(row):
    return "no plate" if row["plate"] is None else f"plate {row['plate'] * 1e3:g} mm"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacing", type=float, default=0.01)
    p.add_argument("--scheme", default="standard")
    p.add_argument(
        "--plates",
        nargs="+",
        default=["none", "0.1", "0.025"],
        help="plate depths [m] below the surface; 'none' for the bare tank",
    )
    p.add_argument("--plate-length", type=float, default=0.1)
    p.add_argument("--freqs", type=float, nargs="+", default=SEED_FREQUENCIES)
    p.add_argument("--amplitude", type=float, default=2e-3)
    p.add_argument("--settle", type=float, default=0.5)
    p.add_argument("--shake", type=float, default=8.0)
    p.add_argument("--release", type=float, default=0.01, help="free decay, m")
    p.add_argument("--periods", type=float, default=4.0)
    p.add_argument("--no-free", action="store_true", help="skip the free decays")
    p.add_argument("--out", type=Path, default=HERE / "results" / "urata_plates_cpu")
    args = p.parse_args(argv)
    rows = []
    for item in args.plates:
        plate = None if item == "none" else float(item)
        row = dict(plate=plate, **forced(plate, args))
        if not args.no_free:
            try:
                row.update(free(plate, args))
            except ValueError as error:  # a release that uncovers a shallow plate
                row["free_refused"] = str(error)
        print(
            json.dumps(
                {k: v for k, v in row.items() if k not in ("free_time", "free_mode")}
            ),
            flush=True,
        )
        rows.append(row)
    info = dict(
        machine=machine_info(),
        **{k: v for k, v in vars(args).items() if k not in ("out", "plates")},
    )
    args.out.with_suffix(".json").write_text(
        json.dumps(dict(info=info, rows=rows), indent=1)
    )
    args.out.with_suffix(".md").write_text(markdown(info, rows))
    print(markdown(info, rows))


if __name__ == "__main__":
    main()
