"""A plate clamped at both ends under a standing water column: the fluid's
pressure against plate theory, and against the same load carried as weight.

`elastic_plate` (span 0.2 m, thickness 0.01 m, E = 2.5e7 Pa, nu = 0.3, rho_s =
1000 kg/m^3, water 0.1 m deep, 2-D plane strain) loaded at once from rest: the
plate oscillates about its static deflection, the mean of a fit of its dominant
mode to the mid-span deflection (`scenes.oscillation_mean`).
Clamped-clamped plate theory: q L^4 / (384 D), D = E t^3 / (12 (1 - nu^2)),
q = rho g H + rho_s g t (1.96 mm); shear adds 12.5 (t / L)^2 (3 %) for a
Timoshenko plate.

The dry twin carries the same load as its own weight (rho_s' = rho_s + rho H / t,
no water): wet / dry isolates the coupling to the fluid, dry / theory the
particle model's own error (which falls with the layers through the thickness:
4, 8).

Run: python validation/elastic_plate.py [--cases dry4 dry8 wet4 wet8]
(default: the first three; writes results/elastic_plate_cpu.{json,md}, keeping the
existing file's rows that were not run again).
"""

import argparse
import dataclasses
import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
SHEAR = 12.5  # x (t / L)^2: 4 E / (kappa G), nu = 0.3, kappa = 5/6


def run(water, spacing, t_end, every=5):
    settings = dict(spacing=spacing)
    if not water:
        base = jaxmps.scenes.elastic_plate(**settings)
        c = base.config
        dense = c["solid_density"] + c["density"] * c["depth"] / c["thickness"]
        settings.update(water=False, solid_density=dense)
    case = jaxmps.scenes.elastic_plate(**settings)
    # Uniform steps of the scene's largest step: saves that land on given times
    # shorten steps, and the dense plate's oscillation degrades under such uneven
    # steps (a Courant failure at saves every 0.2 ms; open).
    dt = float(case.params.dt)
    case = dataclasses.replace(
        case, scene=dataclasses.replace(case.scene, time_step=None)
    )
    theory = jaxmps.scenes.plate_theory(case.config)
    n = round(t_end / dt) // every * every
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        n_steps=n,
        save_every=every,
        observe=jaxmps.scenes.observe_probes(case.probes),
        throw=False,
    )
    wall = time.perf_counter() - start
    w = np.asarray(out.saved["deflection"])
    t = np.asarray(out.saved["time"])
    static, period, periods = jaxmps.scenes.oscillation_mean(t, w)
    first = int(np.argmax(w[: len(w) // 2]))
    rest = w[first:]
    # loaded at once from rest, an undamped plate first swings to twice its
    # static deflection: half the first peak is a second estimate
    first_swing = 0.5 * float(w[first])
    return dict(
        water=water,
        spacing=spacing,
        layers=round(case.config["thickness"] / spacing),
        particles=int(case.state.position.shape[0]),
        dt=float(case.params.dt),
        substeps=case.scene.elastic.substeps,
        theory=theory["deflection"],
        static=float(static),
        first_swing=first_swing,
        period=float(period),
        periods=periods,
        series=[float(v) for v in w],
        ratio=float(static / theory["deflection"]),
        peak_time=float(t[first]),
        range=[float(rest.min()), float(rest.max())],
        result="ok" if out.result == jaxmps.Result.successful else str(out.result)[:80],
        wall_s=wall,
    )


CASES = {  # (water, spacing, t_end)
    "dry4": (False, 0.0025, 0.3),
    "dry8": (False, 0.00125, 0.3),
    "wet4": (True, 0.0025, 0.25),
    "wet8": (True, 0.00125, 0.25),
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases", nargs="+", choices=list(CASES), default=["dry4", "dry8", "wet4"]
    )
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / "elastic_plate_cpu.json"
    chosen = [CASES[name] for name in args.cases]
    rows, info = [], machine_info()
    if path.exists():
        previous = json.loads(path.read_text())
        old = [
            {"host": previous["machine"].get("cpu_model", "?"), **r}
            for r in previous["rows"]
        ]
        rows = [
            r
            for r in old
            if (r["water"], r["spacing"]) not in {(w, sp) for w, sp, _ in chosen}
        ]
    for water, spacing, t_end in chosen:
        rows.append({"host": info.get("cpu_model", "?"), **run(water, spacing, t_end)})
        print(rows[-1], flush=True)
    rows.sort(key=lambda r: (r["water"], -r["spacing"]))
    out = dict(machine=info, shear_factor=SHEAR, rows=rows)
    (HERE / "results" / "elastic_plate_cpu.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Clamped plate under a water column (float64, CPU)",
        "",
        "Span 0.2 m, t = 0.01 m, E = 2.5e7 Pa, nu = 0.3, 0.1 m of water; theory",
        "q L^4 / (384 D) = 1.96 mm (Timoshenko shear: +3.1 %). Static deflection:",
        "mean of a fit of the dominant mode (`scenes.oscillation_mean`).",
        "",
        "| load | layers | particles | dt [s] | sub-steps | static [mm] "
        "| / theory | half the first peak [mm] | / theory | period [s] "
        "| oscillation [mm] | wall [s] | result | host |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {'water' if r['water'] else 'own weight'} | {r['layers']} "
            f"| {r['particles']} | {r['dt']:.3g} | {r['substeps']} "
            f"| {1e3 * r['static']:.3f} | {r['ratio']:.3f} "
            f"| {1e3 * r['first_swing']:.3f} | {r['first_swing'] / r['theory']:.3f} "
            f"| {r['period']:.4f} "
            f"| {1e3 * r['range'][0]:.2f}-{1e3 * r['range'][1]:.2f} "
            f"| {r['wall_s']:.0f} | {r['result']} | {r['host']} |"
        )
    lines.append("")
    for wet in (r for r in rows if r["water"]):
        dry = [r for r in rows if not r["water"] and r["spacing"] == wet["spacing"]]
        if dry:
            ratio, swing = (wet[k] / dry[0][k] for k in ("static", "first_swing"))
            lines.append(
                f"Wet / dry at {wet['layers']} layers: {ratio:.3f} (fit), "
                f"{swing:.3f} (first swing)."
            )
    lines += [
        "",
        f"Machine: {out['machine']}",
    ]
    (HERE / "results" / "elastic_plate_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
