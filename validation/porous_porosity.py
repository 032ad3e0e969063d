"""Porous regions with a porosity: how much water a region holds, whether its
water stands at the hydrostatic pressure of open water, how quiet that pressure
is, and the level water reaches when it flows into a porous bed.

1. Still water (`hydrostatic`, 0.4 m x 0.2 m, l0 = 1 cm; 3-D 0.4 x 0.4 x 0.2 m
   at 2 cm) with a region of porosity phi through the whole depth over
   x = 0.1-0.3 m (kappa = 0.05 s), its fluid thinned to phi at the start
   (`fill_pores`), 60 saves over 0.5-2.5 s: the share of the region's core the
   water holds (against phi), the bottom pressure in the core and in open water
   (their mean ratio, spread, largest excursion, and the saves more than 10 %
   off the mean), against the same tank without porosity.
2. Water flowing into a porous bed (`dam_break`, a 0.3 m x 0.2 m column in a 0.6 m
   tank, the right half porous over a 3 cm wet bed, kappa = 0.05 s): at rest the
   level is h = V / (0.3 (1 + phi)) with V = 0.06 + 0.009 phi m^2 (the bed's
   water thinned to phi); the open water's level (the fluid volume of the strip
   x < 0.2 m over its width), the mean of the last 0.5 s of 3 s, against it and
   against the level without porosity.

The still-water rows go below `fluid.lowest_porosity` (its `LEAST_SHARE` lowered
for this script) to show why the floor lies where it does; the table marks them.

Run: python validation/porous_porosity.py
(writes results/porous_porosity_cpu.{json,md})
"""

import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps
from jaxmps import Kind, fluid
from jaxmps.fluid import _porous as porous_module

HERE = pathlib.Path(__file__).parent
KAPPA = 0.05
DEFAULT_SHARE = porous_module.LEAST_SHARE


def still(scheme, phi, dim, spacing):
    lowered, porous_module.LEAST_SHARE = porous_module.LEAST_SHARE, DEFAULT_SHARE
    plain = jaxmps.scenes.hydrostatic(spacing=spacing, scheme=scheme, dim=dim)
    floor = fluid.lowest_porosity(plain.scene.discretisation)
    porous_module.LEAST_SHARE = lowered
    settings = dict(
        width=0.4, depth=0.2, spacing=spacing, dim=dim, scheme=scheme, dt=0.1 * spacing
    )
    box = "0.1,-1,0.3,1" if dim == 2 else "0.1,-1,-1,0.3,1,1"
    if phi < 1:
        settings.update(
            porous_kappa=KAPPA,
            porous_box=box,
            porous_direction="all",
            porous_porosity=phi,
        )
    case = jaxmps.scenes.hydrostatic(**settings)
    times = np.linspace(0.5, 2.5, 60)
    start = time.perf_counter()
    out = jaxmps.simulate(case.scene, case.params, case.state, times=times, throw=False)
    wall = time.perf_counter() - start
    water = np.asarray(case.state.kind) == int(Kind.FLUID)
    up = dim - 1
    share, core_p, open_p = [], [], []
    for k in range(len(times)):
        live = np.asarray(out.saved.active[k]) & water
        x = np.asarray(out.saved.position[k])
        p = np.asarray(out.saved.pressure[k])
        core = live & (x[:, 0] > 0.1 + 3 * spacing) & (x[:, 0] < 0.3 - 3 * spacing)
        open_ = live & ((x[:, 0] < 0.1 - 3 * spacing) | (x[:, 0] > 0.3 + 3 * spacing))
        core_width = 0.2 - 6 * spacing
        cross = core_width * 0.4 ** (dim - 2)
        share.append(np.sum(core & (x[:, up] < 0.15)) * spacing**dim / (cross * 0.15))
        bottom = x[:, up] < 2 * spacing
        core_p.append(p[core & bottom].mean())
        open_p.append(p[open_ & bottom].mean())
    core_p, open_p = np.array(core_p), np.array(open_p)

    def spread(values):
        mean = values.mean()
        return dict(
            mean=float(mean),
            std=float(values.std() / mean),
            largest=float(np.abs(values / mean - 1).max()),
            off_10=int(np.sum(np.abs(values / mean - 1) > 0.1)),
        )

    return dict(
        scheme=scheme,
        dim=dim,
        spacing=spacing,
        phi=phi,
        floor=floor,
        result="ok" if out.result == jaxmps.Result.successful else str(out.result),
        share=float(np.mean(share)),
        core=spread(core_p),
        open=spread(open_p),
        core_over_open=float(core_p.mean() / open_p.mean()),
        wall_s=wall,
    )


def filling(phi, spacing, scheme="standard", t_end=3.0):
    settings = dict(
        column_width=0.3,
        column_height=0.2,
        tank_length=0.6,
        tank_height=0.35,
        bed_depth=0.03,
        spacing=spacing,
        scheme=scheme,
        porous_kappa=KAPPA,
        porous_box="0.3,-1,2,2",
        porous_direction="all",
        porous_porosity=phi,
    )
    case = jaxmps.scenes.dam_break(**settings)
    times = np.linspace(t_end - 0.5, t_end, 11)
    start = time.perf_counter()
    out = jaxmps.simulate(case.scene, case.params, case.state, times=times, throw=False)
    wall = time.perf_counter() - start
    water = np.asarray(case.state.kind) == int(Kind.FLUID)
    levels = []
    for k in range(len(times)):
        live = np.asarray(out.saved.active[k]) & water
        x = np.asarray(out.saved.position[k])
        levels.append(np.sum(live & (x[:, 0] < 0.2)) * spacing**2 / 0.2)
    level = float(np.mean(levels))
    analytic = (0.06 + 0.009 * phi) / (0.3 * (1 + phi))
    open_water = (0.06 + 0.009) / 0.6
    return dict(
        phi=phi,
        spacing=spacing,
        scheme=scheme,
        result="ok" if out.result == jaxmps.Result.successful else str(out.result),
        level=level,
        analytic=analytic,
        error_l0=(level - analytic) / spacing,
        without_porosity=open_water,
        wall_s=wall,
    )


def main():
    jax.config.update("jax_enable_x64", True)
    porous_module.LEAST_SHARE = 0.6  # rows below the default floor too
    rows = []
    for scheme in ("standard", "standard_ds"):
        for phi in (1.0, 0.95, 0.9, 0.8, 0.7):
            rows.append(still(scheme, phi, 2, 0.01))
            print(rows[-1], flush=True)
    for phi in (1.0, 0.85, 0.75):
        rows.append(still("standard", phi, 3, 0.02))
        print(rows[-1], flush=True)
    fills = []
    for phi in (1.0, 0.9, 0.8, 0.7):
        fills.append(filling(phi, 0.01))
        print(fills[-1], flush=True)
    porous_module.LEAST_SHARE = DEFAULT_SHARE
    record = dict(still=rows, filling=fills, machine=machine_info())
    (HERE / "results" / "porous_porosity_cpu.json").write_text(
        json.dumps(record, indent=1)
    )
    lines = [
        "# Porous regions with a porosity (CPU, float64)",
        "",
        "Still water, 0.4 m wide, 0.2 m deep, a region through the whole depth over",
        "x = 0.1-0.3 m (kappa 0.05 s, its water thinned to phi at the start), dt = 0.1 "
        "l0, 60 saves over 0.5-2.5 s. Share: the water the region's core holds over "
        "its volume (below 0.15 m). Bottom pressure: the mean over the particles "
        "within 2 l0 of the floor, in the core and in open water; spread = std / "
        "mean over the saves; largest = the largest |p / mean - 1|; off = saves "
        "more than 10 % off. Floor: `fluid.lowest_porosity` of the scheme (rows "
        "below it, marked *, are refused by default).",
        "",
        "| scheme | d | l0 [m] | phi | share | core / open pressure | core spread "
        "| core largest | core off | open spread | open largest | open off | "
        "result | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        c, o = r["core"], r["open"]
        lines.append(
            f"| {r['scheme']} | {r['dim']} | {r['spacing']} | {r['phi']}"
            f"{'*' if r['phi'] < r['floor'] else ''} (floor {r['floor']}) | "
            f"{r['share']:.3f} | {r['core_over_open']:.3f} | {100 * c['std']:.1f} % "
            f"| {100 * c['largest']:.0f} % | {c['off_10']} | {100 * o['std']:.1f} % | "
            f"{100 * o['largest']:.0f} % | {o['off_10']} | {r['result']} | "
            f"{r['wall_s']:.0f} |"
        )
    lines += [
        "",
        "Water flowing into a porous bed (a 0.3 x 0.2 m column, the right half of a "
        "0.6 m tank porous over a 3 cm bed; the open water's level, mean of 2.5-3 s):",
        "",
        "| phi | l0 [m] | level [m] | analytic [m] | error [l0] | "
        "without porosity [m] | result | wall [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for f in fills:
        lines.append(
            f"| {f['phi']} | {f['spacing']} | {f['level']:.4f} | {f['analytic']:.4f} "
            f"| {f['error_l0']:+.2f} | {f['without_porosity']:.4f} | "
            f"{f['result']} | {f['wall_s']:.0f} |"
        )
    lines += ["", f"Machine: {record['machine']}"]
    (HERE / "results" / "porous_porosity_cpu.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
