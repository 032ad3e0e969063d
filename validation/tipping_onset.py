"""Where a rigid block on a slope tips over its lower edge, and whether one that
stands stays still.

A block (`friction_tilt`, friction torque on, mu = 1.5: too rough to slide) under
gravity tilted to tan(theta) around its static tipping limit: the resultant of its
weight leaves its base where tan(theta) > (width - l0) / (height - l0) (its
outermost particles' centres carry the contact). For each ratio: the largest
tilt in 2 s, the travel along the slope, and whether it toppled (a tilt beyond 60
degrees). A cube and a block twice as tall as wide, 2-D (l0 = 0.1 m) and a cube
in 3-D (l0 = 0.2 m). Then on another body: a block resting on a 3 m base block
(`block_stack`, 2-D, l0 = 0.05 m, mu = 2 between them and against the floor,
1.5 s after the scene's settling), a square and a block twice as tall as wide;
there the contact's face reaches to where the two lattices meet, half a spacing
beyond the corner particles, so the solid's limit w / h is given beside.

With --water: the blocks on a base block again, in still water and dry side by
side (a 1 m base on a 1.5 m floor, so that the tilted water stays in a small tank;
water `--above` m over the stack's top at the block's middle). Whether water
reaches under a block decides its limit: with the full buoyancy at its centroid
the submerged weight tips it where the dry weight does, tan(theta) = w / h;
without the pressure under its base (the scene's blocks rest lattice on lattice)
the water's load on its top and sides holds it beyond. Either way it must not tip
before the dry limit: that is what is asserted.

Run: python validation/tipping_onset.py [--water] [--above 0.3]
(writes results/tipping_onset_cpu.{json,md}, with --water
results/tipping_onset_water_cpu.{json,md})
"""

import argparse
import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps
from jaxmps._result import result_name

HERE = pathlib.Path(__file__).parent
G, T, MU = 9.81, 2.0, 1.5
# (name, dim, width, height, spacing, ratios of tan(theta) to the limit)
CASES = (
    ("cube", 2, 1.0, 1.0, 0.1, (0.9, 0.95, 0.98, 1.02, 1.05, 1.1)),
    ("tall", 2, 0.5, 1.0, 0.1, (0.9, 0.95, 0.98, 1.02, 1.05, 1.1)),
    ("cube", 3, 1.0, 1.0, 0.2, (0.9, 0.98, 1.02, 1.1)),
)


# (name, width, height, spacing, ratios): blocks on a base block
ON_BODY = (
    ("square", 0.5, 0.5, 0.05, (0.9, 0.97, 1.03, 1.1)),
    ("tall", 0.3, 0.6, 0.05, (0.9, 0.97, 1.03, 1.06, 1.08, 1.12, 1.2)),
)
T_ON_BODY = 1.5


def tilt_angle(orientation: np.ndarray, dim: int) -> np.ndarray:
    """The body's tilt from upright [degrees]: the angle in 2-D, the rotation
    angle of the unit quaternion in 3-D (so 180 at most: a cube that rolled on
    over two edges reads upright again, hence toppling is read from the largest
    tilt)."""
    if dim == 2:
        return np.degrees(np.abs(orientation[..., 0]))
    w = np.clip(np.abs(orientation[..., 0]), 0.0, 1.0)
    return np.degrees(2 * np.arccos(w))


def run(name, dim, width, height, l0, ratios):
    case = jaxmps.scenes.friction_tilt(
        dim=dim,
        spacing=l0,
        block_size=width,
        block_height=height,
        friction_torque=True,
        mu_static=MU,
        mu_kinetic=MU,
    )
    limit = (width - l0) / (height - l0)
    theta = np.arctan(limit * np.asarray(ratios))
    gravity = np.zeros((len(ratios), dim))
    gravity[:, 0], gravity[:, -1] = G * np.sin(theta), -G * np.cos(theta)
    saves = 40
    n = saves * round(T / float(case.params.dt) / saves)
    start = time.perf_counter()
    out = jaxmps.sweep(
        case,
        {"gravity": gravity},
        n_steps=n,
        save_every=n // saves,
        observe=lambda scene, state: state.rigid,
    )
    wall = time.perf_counter() - start
    tilt = tilt_angle(np.asarray(out.saved.orientation)[:, :, 0], dim)
    travel = np.asarray(out.saved.centre)[:, -1, 0, 0] - float(
        case.state.rigid.centre[0, 0]
    )
    return [
        dict(
            block=name,
            dim=dim,
            width=width,
            height=height,
            spacing=l0,
            limit=limit,
            ratio=float(r),
            tan=float(limit * r),
            largest_tilt_deg=float(tilt[k].max()),
            travel_m=float(travel[k]),
            toppled=bool(tilt[k].max() > 60.0),
            result=int(np.asarray(out.result)[k]),
            wall_s=wall,
        )
        for k, r in enumerate(ratios)
    ]


def run_on_body(name, width, height, l0, ratios, water=None, base=3.0, floor=4.0):
    """The block on a base block `base` m wide for each ratio; in still water
    `water` m over the stack's top when given."""
    limit = (width - l0) / (height - l0)
    rows = []
    for r in ratios:
        wet = {} if water is None else dict(water_depth=2 * height + water)
        case = jaxmps.scenes.block_stack(
            block_size=width,
            block_height=height,
            base_width=base,
            floor_length=floor,
            spacing=l0,
            dt=0.001,
            mu_static=2.0,
            angle=float(np.degrees(np.arctan(limit * r))),
            **wet,
        )
        n = round(T_ON_BODY / float(case.params.dt))
        start = time.perf_counter()
        out = jaxmps.simulate(
            case.scene,
            case.params,
            case.state,
            n,
            n // 30,
            observe=lambda scene, state: state.rigid,
            throw=False,
        )
        tilt = tilt_angle(np.asarray(out.saved.orientation)[:, 1], 2)
        travel = np.asarray(out.saved.centre)[-1, 1, 0] - float(
            case.state.rigid.centre[1, 0]
        )
        rows.append(
            dict(
                block=name,
                width=width,
                height=height,
                spacing=l0,
                limit=limit,
                solid_limit=width / height,
                ratio=float(r),
                tan=float(limit * r),
                water_above=water,
                particles=int(np.asarray(case.state.active).sum()),
                tilt_at_release_deg=float(
                    tilt_angle(np.asarray(case.state.rigid.orientation)[1], 2)
                ),
                largest_tilt_deg=float(tilt.max()),
                travel_m=float(travel),
                toppled=bool(tilt.max() > 60.0),
                result=result_name(out.result),
                wall_s=time.perf_counter() - start,
            )
        )
    return rows


# (name, width, height, spacing, ratios): in water and dry, on a 1 m base
IN_WATER = (
    ("square", 0.5, 0.5, 0.05, (0.9, 0.97, 1.03, 1.1, 1.2)),
    ("tall", 0.3, 0.6, 0.05, (0.9, 0.97, 1.03, 1.1, 1.2)),
)


def main_water(above: float) -> None:
    rows = [
        row
        for water in (above, None)
        for case in IN_WATER
        for row in run_on_body(*case, water=water, base=1.0, floor=1.5)
    ]
    out = dict(machine=machine_info(), mu=2.0, t_end=T_ON_BODY, rows=rows)
    stem = HERE / "results" / "tipping_onset_water_cpu"
    stem.with_suffix(".json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Tipping onset of a block on a block, in still water and dry (float64, CPU)",
        "",
        "Script: `validation/tipping_onset.py --water`. `block_stack`: the block on "
        f"a 1 m base block on a 1.5 m floor, l0 = 0.05 m, mu = 2, {T_ON_BODY} s "
        "after the scene's settling; in water the surface is level under the "
        f"tilted gravity, {above:g} m over the stack's top at the block's middle. "
        "Limit: the particles' (width - l0) / (height - l0). Host: "
        f"{out['machine'].get('cpu_model') or '?'}.",
        "",
        "| block | water | particles | tan(theta) / limit | tan(theta) | largest "
        "tilt [deg] | travel [m] | toppled | result | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        wet = "dry" if r["water_above"] is None else f"{r['water_above']:g} m over"
        lines.append(
            f"| {r['block']} {r['width']:g} x {r['height']:g} m | {wet} | "
            f"{r['particles']} | {r['ratio']:g} | {r['tan']:.3f} | "
            f"{r['largest_tilt_deg']:.2f} | {r['travel_m']:.4f} | "
            f"{'yes' if r['toppled'] else 'no'} | {r['result']} | "
            f"{r['wall_s']:.0f} |"
        )
    lines.append("")
    for name, *_ in IN_WATER:
        for water in (above, None):
            sub = [r for r in rows if r["block"] == name and r["water_above"] == water]
            stands = max([r["ratio"] for r in sub if not r["toppled"]], default=None)
            tips = min([r["ratio"] for r in sub if r["toppled"]], default=None)
            lines.append(
                f"- {name}, {'dry' if water is None else 'in water'}: stands up to "
                f"{stands} x the limit, topples from {tips} x"
            )
    stem.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--water", action="store_true")
    parser.add_argument("--above", type=float, default=0.3)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    if args.water:
        main_water(args.above)
        return
    rows = [row for case in CASES for row in run(*case)]
    on_body = [row for case in ON_BODY for row in run_on_body(*case)]
    out = dict(
        machine=machine_info(),
        mu=MU,
        t_end=T,
        rows=rows,
        on_body=dict(mu=2.0, t_end=T_ON_BODY, rows=on_body),
    )
    (HERE / "results" / "tipping_onset_cpu.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Tipping onset of a block on a slope (float64, CPU)",
        "",
        f"Script: `validation/tipping_onset.py`. `friction_tilt`, friction torque "
        f"on, mu = {MU}, {T} s. The static limit is tan(theta) = (width - l0) / "
        "(height - l0).",
        "",
        "| block | dim | l0 [m] | limit | tan(theta) / limit | largest tilt [deg] "
        "| travel [m] | toppled | result |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['block']} {r['width']:g} x {r['height']:g} m | {r['dim']} | "
            f"{r['spacing']:g} | {r['limit']:.3f} | {r['ratio']:g} | "
            f"{r['largest_tilt_deg']:.2f} | {r['travel_m']:.4f} | "
            f"{'yes' if r['toppled'] else 'no'} | {r['result']} |"
        )
    lines.append("")
    for name, dim, *_ in CASES:
        sub = [r for r in rows if r["block"] == name and r["dim"] == dim]
        stands = max([r["ratio"] for r in sub if not r["toppled"]], default=None)
        tips = min([r["ratio"] for r in sub if r["toppled"]], default=None)
        lines.append(
            f"- {dim}-D {name}: stands up to {stands} x the limit, topples from "
            f"{tips} x"
        )
    lines += [
        "",
        "## On another body",
        "",
        f"`block_stack`: the block on a 3 m base block, l0 = 0.05 m, mu = 2, "
        f"{T_ON_BODY} s after the scene's settling. The particles' limit is "
        "(width - l0) / (height - l0), the solid's width / height.",
        "",
        "| block | limit | solid's limit | tan(theta) / limit | tan(theta) | tilt at "
        "release [deg] | largest tilt [deg] | travel [m] | toppled | result |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in on_body:
        lines.append(
            f"| {r['block']} {r['width']:g} x {r['height']:g} m | {r['limit']:.3f} | "
            f"{r['solid_limit']:.3f} | {r['ratio']:g} | {r['tan']:.3f} | "
            f"{r['tilt_at_release_deg']:.2f} | {r['largest_tilt_deg']:.2f} | "
            f"{r['travel_m']:.4f} | {'yes' if r['toppled'] else 'no'} | "
            f"{r['result']} |"
        )
    lines.append("")
    for name, *_ in ON_BODY:
        sub = [r for r in on_body if r["block"] == name]
        stands = max([r["tan"] for r in sub if not r["toppled"]], default=None)
        tips = min([r["tan"] for r in sub if r["toppled"]], default=None)
        lines.append(
            f"- {name} on a block: stands up to tan = {stands:.3f}, topples from "
            f"{tips:.3f} (solid's limit {sub[0]['solid_limit']:.3f})"
        )
    (HERE / "results" / "tipping_onset_cpu.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
