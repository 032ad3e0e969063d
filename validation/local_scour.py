"""Seed 002's local scour below a groundsill (Case 2-2, its Ch. 6 E-MPS-DEM
simulation, V5) with `jaxmps.scenes.local_scour`.

A groundsill (crest 3 cm, a 2 cm drop, apron 10 cm), a 29 cm flat reach and a
0.5 m transition falling by Delta H = 2 cm, the lowered bed to a free overfall at
1.12 m; q = 0.012 m^2/s fed at the critical depth; from the apron's end 37.5 cm of
DEM grains (d = l0, R = 1.25, mu = 0.577, seed 002's packed bed 7 cm deep,
attached to the bed until the flow moves them); explicit E-MPS (c = 10 m/s,
facing wall pressure). The grains feel no flow for `--release` s (the seed: 10 s
with the grains fixed), then the jet digs for `--main` s (the seed: 50 s).

Seed 002 (d = l0 = 1 mm): the bed steady by ~30 s, the hole L = 43.5 cm, Z_d =
5.8 cm (experiment after 10 min: 42.5 / 4.9 cm). Its gate for us: L within ±15 %
(37-50 cm), Z_d 4.4-6.5 cm. The hole scales with the grain, which is the spacing
here: at a coarser spacing the grains are coarser than the seed's sand.

Measured from the saves: the hole's depth and length (the scene's probes
`scour_depth`, `scour_length`: the bed lowered by more than one grain below its
surface at release, the run round the deepest point), the time the depth first
reaches 90 % of its final value, the bed's profile at several times.

Run: PYTHONPATH=. python validation/local_scour.py [--spacing 0.0025]
[--release 2] [--main 18] (writes results/local_scour_<tag>_cpu.{json,md,png}).
"""

import argparse
import json
import time

import jax
import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps.scenes import BedLowering

jax.config.update("jax_enable_x64", True)

SEED_DIAMETER = 0.001  # seed 002 Ch. 6: d = l0 = 1 mm, R = 1.25


def profiles(case, frames) -> tuple[np.ndarray, np.ndarray]:
    """The bed's surface in each save (saves, bins) and the bins' centres, as
    the scene's `BedLowering` probes see it."""
    probe = next(p for p in case.probes if isinstance(p, BedLowering))
    index = np.asarray(case.state.grains.index)
    position = np.asarray(frames.position)[:, index]
    in_bed = np.asarray(frames.bodies["attached"]) | (
        np.asarray(frames.bodies["contact_count"]) >= 2
    )
    where = dict(
        x0=probe.x0, width=probe.width, floor=probe.floor, diameter=probe.diameter
    )
    surface = np.stack(
        [
            BedLowering.surface_of(p, b, probe.bins, **where)
            for p, b in zip(position, in_bed)
        ]
    )
    return surface, probe.x0 + (np.arange(probe.bins) + 0.5) * probe.width


def water_surface(case, frames, k: int, x: np.ndarray) -> np.ndarray:
    """The water's surface over the bins `x` in save `k`: the highest active fluid
    particle (+ l0/2) within each bin."""
    l0 = case.config["spacing"]
    kind = np.asarray(case.state.kind)
    fluid = np.asarray(frames.active)[k] & (kind == int(jaxmps.Kind.FLUID))
    p = np.asarray(frames.position)[k][fluid]
    width = x[1] - x[0]
    out = np.full(len(x), np.nan)
    b = np.floor((p[:, 0] - (x[0] - 0.5 * width)) / width).astype(int)
    ok = (b >= 0) & (b < len(x))
    for i, y in zip(b[ok], p[ok, 1]):
        out[i] = y + 0.5 * l0 if np.isnan(out[i]) else max(out[i], y + 0.5 * l0)
    return out


def grain_density(args) -> float:
    """The grains' density: the seed's R = 1.25 (2250 kg/m^3), or with
    `--similar` the R that keeps the seed's Shields number u*^2 / (R g d) and
    (for Newton drag) its settling speed ~ sqrt(R g d) at a coarser grain: R =
    1.25 x 1 mm / d, the lightweight model sediment of a physical model."""
    if args.grain_density is not None:
        return args.grain_density
    if args.similar:
        return 1000.0 * (1.0 + 1.25 * SEED_DIAMETER / args.spacing)
    return 2250.0


def run(args) -> dict:
    case = jaxmps.scenes.local_scour(
        spacing=args.spacing,
        release_time=args.release,
        t_end=args.release + args.main,
        grain_density=grain_density(args),
    )
    observe_probes = jaxmps.scenes.observe_probes(case.probes)
    times = np.round(np.arange(1, round(case.t_end / args.every) + 1) * args.every, 9)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=times,
        observe=lambda s, st: (jaxmps.frame(s, st), observe_probes(s, st)),
        throw=False,
    )
    frames, probes = out.saved
    jax.block_until_ready(probes)
    wall = time.perf_counter() - start
    surface, x = profiles(case, frames)
    at_release = int(np.argmin(np.abs(times - args.release)))
    depth = np.asarray(probes["scour_depth"])
    length = np.asarray(probes["scour_length"])
    final = float(depth[-1])
    reached = np.nonzero(depth >= 0.9 * final)[0] if final > 0 else []
    picks = sorted(
        {at_release, *np.linspace(at_release, len(times) - 1, 4).astype(int).tolist()}
    )
    return dict(
        spacing=args.spacing,
        grain_density=grain_density(args),
        particles=int(np.asarray(case.state.active).sum()),
        grains=int(case.scene.grains.count),
        slots=int(case.scene.capacity),
        dt=float(case.params.dt),
        substeps=int(case.scene.grains.substeps),
        stiffness=float(case.params.grains.stiffness),
        steps=int(round(case.t_end / float(case.params.dt))),
        wall_s=round(wall, 1),
        result=jaxmps._result.result_name(out.result),
        times=[round(float(t), 3) for t in times],
        scour_depth=[round(float(v), 5) for v in depth],
        scour_length=[round(float(v), 5) for v in length],
        final_depth=final,
        final_length=float(length[-1]),
        steady_at=None if not len(reached) else float(times[reached[0]]),
        grains_detached=int((~np.asarray(frames.bodies["attached"][-1])).sum()),
        grains_carried_out=int(
            (~np.asarray(frames.active)[-1][np.asarray(case.state.grains.index)]).sum()
        ),
        x=[round(float(v), 5) for v in x],
        profiles={
            f"{times[k]:g}": [round(float(v), 5) for v in surface[k]] for k in picks
        },
        water={
            f"{times[k]:g}": [
                None if np.isnan(v) else round(float(v), 5)
                for v in water_surface(case, frames, k, x)
            ]
            for k in picks[-1:]
        },
    )


def markdown(args, r, info) -> str:
    seed_l, seed_z = jaxmps.scenes.MEASURED_SCOUR["seed simulation"]
    exp_l, exp_z = jaxmps.scenes.MEASURED_SCOUR["experiment"]
    return "\n".join(
        [
            f"# Local scour (seed 002 Case 2-2, Ch. 6): l0 = d = {1e3 * r['spacing']:g}"
            " mm",
            "",
            f"Grains of {r['grain_density']:g} kg/m^3 (R = "
            f"{r['grain_density'] / 1000 - 1:.3g}; the seed's 1.25 at 1 mm). "
            f"{args.release:g} s with the grains feeling no flow, then {args.main:g} s"
            f" of scour; {r['particles']} particles ({r['grains']} grains), dt "
            f"{r['dt']:.3g} s, {r['substeps']} DEM sub-step(s), k_n "
            f"{r['stiffness']:.4g} N/m (seed 002's rule), {r['steps']} steps in "
            f"{r['wall_s']:.0f} s ({r['result']}). Host: "
            f"{info.get('cpu_model') or '?'}, float64.",
            "",
            "| | L [cm] | Z_d [cm] | depth at 90 % of final [s] |",
            "|---|---|---|---|",
            f"| this run ({args.main:g} s) | {100 * r['final_length']:.1f} | "
            f"{100 * r['final_depth']:.2f} | {r['steady_at']} |",
            f"| seed 002 simulation (1 mm, 50 s) | {100 * seed_l:.1f} | "
            f"{100 * seed_z:.1f} | ~30 s (bed steady) |",
            f"| experiment (10 min) | {100 * exp_l:.1f} | {100 * exp_z:.1f} | - |",
            "| gate (V5) | 37-50 | 4.4-6.5 | |",
            "",
            f"Grains detached by the end: {r['grains_detached']} of {r['grains']}; "
            f"carried out over the overfall: {r['grains_carried_out']}.",
            "",
        ]
    )


def plot(r, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(2, 1, figsize=(10, 7))
    x = np.asarray(r["x"])
    for t, z in r["profiles"].items():
        ax.plot(x, np.asarray(z) * 100, label=f"bed at {t} s")
    for t, z in r["water"].items():
        ax.plot(x, np.asarray(z, float) * 100, "b:", label=f"water at {t} s")
    ax.set_xlabel("x [m] (crest at 0, apron ends at the first bin)")
    ax.set_ylabel("height [cm] (crest at 0)")
    ax.legend(fontsize=7)
    bx.plot(r["times"], np.asarray(r["scour_depth"]) * 100, label="depth Z_d [cm]")
    bx.plot(r["times"], np.asarray(r["scour_length"]) * 100, label="length L [cm]")
    bx.set_xlabel("time [s]")
    bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacing", type=float, default=0.0025)
    parser.add_argument("--release", type=float, default=2.0)
    parser.add_argument("--main", type=float, default=18.0)
    parser.add_argument("--every", type=float, default=0.5)
    parser.add_argument("--grain-density", type=float, default=None)
    parser.add_argument(
        "--similar",
        action="store_true",
        help="grains as mobile as the seed's 1 mm sand (R = 1.25 mm / d)",
    )
    parser.add_argument("--tag", default=None)
    args = parser.parse_args()
    tag = args.tag or f"{args.spacing * 1e3:g}mm".replace(".", "p")
    tag += "_similar" * args.similar
    stem = HERE / "results" / f"local_scour_{tag}_cpu"
    info = machine_info()
    r = run(args)
    path = {ext: stem.parent / f"{stem.name}.{ext}" for ext in ("json", "md", "png")}
    path["json"].write_text(
        json.dumps(dict(args=vars(args), machine=info, run=r), indent=1)
    )
    path["md"].write_text(markdown(args, r, info))
    plot(r, path["png"])
    print(markdown(args, r, info))


if __name__ == "__main__":
    main()
