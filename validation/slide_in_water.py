"""A block on a slope in still water (seed 002's T10), against linear potential
flow: it stays where tan(theta) < mu, and where it slides its travel is the
theory's, the water's added mass included.

Seed 002 states the sliding acceleration as (W / M)(sin theta - mu cos theta) g,
W the submerged weight: that leaves out the water the block must push aside,
which at the release weighs more than the block (a square on the floor of a
closed tank: 1.8 x its mass at 1.5 x the water's density). The reference here
(`_slide_theory.py`) solves the same tank in linear potential flow: the
impulsive added mass at the release, the free surface's rise after it, the
submerged-weight friction.

Cases (`friction_tilt` with water, `friction_normal="submerged_weight"`, each
friction coefficient a member of one `jaxmps.sweep`; float64; default scheme):
- `t10`: the slow test's tank: a 1 m square block of 1.5 x the water's density,
  tan(theta) = 0.5, water 1.5 m deep at the block, a 3 m tank; mu = 0, 0.25
  (slides) and 0.55 (stays); l0 = 0.1 and 0.05 m.
- `finer`: the same frictionless at l0 = 0.025 m; `t10_ds`: mu = 0 and 0.25 at
  l0 = 0.1 and 0.05 m with dynamic stabilisation (`scheme="standard_ds"`);
  `t10_ha`: the same with the high-accuracy scheme at l0 = 0.1, 0.05 and 0.025 m.
- `seed`: the seed's mu = 0.6: a 0.5 x 0.3 m block of 2.3 x the water's density
  in water 1 m deep, a 2.5 m tank, tan(theta) = 0.55 (stays) and 0.7 (slides);
  and the frictionless slide at tan(theta) = 0.7; l0 = 0.05 m.
- `long`: a 1 m square of 2 x the water's density in a 6 m tank 2 m deep,
  tan(theta) = 0.4, mu = 0 and 0.2, over 0.5 s; l0 = 0.1 m.

Run: python validation/slide_in_water.py  (results/slide_in_water_cpu.{json,md})
     --cases t10 seed long (default all), --fresh (rerun stored cases)
"""

import argparse
import json
import math
import pathlib
import time

import jax
import numpy as np
from _common import machine_info
from _slide_theory import slide

import jaxmps

HERE = pathlib.Path(__file__).parent
STAY = 1e-3  # [m]: travel below this over the run counts as staying

CASES = {
    "t10": [
        dict(spacing=s, size=1.0, height=None, ratio=1.5, depth=1.5, floor=3.0,
             tan=0.5, mus=(0.0, 0.25, 0.55), t_end=0.3)
        for s in (0.1, 0.05)
    ],
    "finer": [
        dict(spacing=0.025, size=1.0, height=None, ratio=1.5, depth=1.5, floor=3.0,
             tan=0.5, mus=(0.0,), t_end=0.3)
    ],
    "t10_ds": [
        dict(spacing=s, size=1.0, height=None, ratio=1.5, depth=1.5, floor=3.0,
             tan=0.5, mus=(0.0, 0.25), t_end=0.3, scheme="standard_ds")
        for s in (0.1, 0.05)
    ],
    "t10_ha": [
        dict(spacing=s, size=1.0, height=None, ratio=1.5, depth=1.5, floor=3.0,
             tan=0.5, mus=(0.0, 0.25), t_end=0.3, scheme="high_accuracy")
        for s in (0.1, 0.05, 0.025)
    ],
    "seed": [
        dict(spacing=0.05, size=0.5, height=0.3, ratio=2.3, depth=1.0, floor=2.5,
             tan=tan, mus=mus, t_end=0.3)
        for tan, mus in ((0.55, (0.6,)), (0.7, (0.0, 0.6)))
    ],
    "long": [
        dict(spacing=0.1, size=1.0, height=None, ratio=2.0, depth=2.0, floor=6.0,
             tan=0.4, mus=(0.0, 0.2), t_end=0.5)
    ],
}  # fmt: skip


def run(name: str, c: dict) -> list[dict]:
    case = jaxmps.scenes.friction_tilt(
        spacing=c["spacing"],
        block_size=c["size"],
        block_height=c["height"],
        density_ratio=c["ratio"],
        water_depth=c["depth"],
        floor_length=c["floor"],
        angle=math.degrees(math.atan(c["tan"])),
        friction_normal="submerged_weight",
        scheme=c.get("scheme", "standard"),
    )
    mus = np.asarray(c["mus"])
    times = np.round(np.linspace(0.1, c["t_end"], round(c["t_end"] / 0.1)), 6)
    start = time.perf_counter()
    out = jaxmps.sweep(
        case,
        {"rigid.mu_static": mus[:, None], "rigid.mu_kinetic": mus[:, None]},
        times=times,
    )
    wall = time.perf_counter() - start
    travel = np.asarray(out.saved["block_x"]) - float(case.state.rigid.centre[0, 0])
    block = np.asarray(case.state.rigid.body) == 0
    x0 = float(np.min(np.asarray(case.state.position)[block, 0]))
    cfg = case.config
    rows = []
    for m, mu in enumerate(mus):
        theory = slide(
            length=cfg["floor_length"],
            x0=x0 - c["spacing"] / 2,
            width=cfg["block_size"],
            height=cfg["block_height"],
            depth=c["depth"],
            tan_theta=c["tan"],
            density_ratio=c["ratio"],
            mu=float(mu),
            times=tuple(times),
        )
        rows.append(
            dict(
                case=name,
                **{k: v for k, v in c.items() if k != "mus"},
                mu=float(mu),
                times=times.tolist(),
                travel=travel[m].tolist(),
                theory=theory["travel"],
                added_mass_impulsive=theory["added_mass_impulsive"],
                added_mass_rigid_lid=theory["added_mass_rigid_lid"],
                block_mass=theory["mass"],
                seed_formula=_seed_formula(c, float(mu), times),
                result=int(np.asarray(out.result)[m]),
                particles=int(case.state.position.shape[0]),
                wall_s=wall,
            )
        )
    return rows


def _seed_formula(c, mu, times):
    """Seed 002's travel (W / M)(sin - mu cos) g t^2 / 2, no added mass."""
    cos = 1 / math.sqrt(1 + c["tan"] ** 2)
    a = (1 - 1 / c["ratio"]) * 9.81 * max(0.0, c["tan"] * cos - mu * cos)
    return [a * t * t / 2 for t in times]


def _verdict(r) -> str:
    if r["tan"] < r["mu"]:
        return "stays" if abs(r["travel"][-1]) < STAY else "MOVES"
    ratio = r["travel"][-1] / r["theory"][-1]
    return f"{ratio:.3f}" + ("" if abs(ratio - 1) <= 0.1 else " (outside 10 %)")


def write(rows, info):
    name = HERE / "results" / "slide_in_water_cpu"
    name.with_suffix(".json").write_text(
        json.dumps(dict(machine=info, rows=rows), indent=1)
    )
    lines = [
        "# A block on a slope in still water against linear potential flow (T10)",
        "",
        f"Script: `validation/slide_in_water.py`; host: {info['cpu_model']}, "
        f"{info['cpu_count']} cores; float64, submerged-weight "
        "friction. Travel along the floor at the end of the run against the "
        "potential-flow theory of the same tank (`_slide_theory.py`: added mass "
        "m_a at the release and with a rigid lid, per the block's mass M) and "
        "against seed 002's formula without the water's inertia.",
        "",
        "| case | scheme | l0 [m] | block [m] | rho_b / rho | tan | mu | t [s] "
        "| travel [mm] | theory [mm] | travel / theory | seed formula [mm] "
        "| m_a / M (release; lid) | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        block = f"{r['size']:g} x {r['height'] or r['size']:g}"
        lines.append(
            f"| {r['case']} | {r.get('scheme', 'standard')} | {r['spacing']:g} | "
            f"{block} | {r['ratio']:g} | "
            f"{r['tan']:g} | {r['mu']:g} | {r['times'][-1]:g} | "
            f"{1e3 * r['travel'][-1]:.2f} | {1e3 * r['theory'][-1]:.2f} | "
            f"{_verdict(r)} | {1e3 * r['seed_formula'][-1]:.2f} | "
            f"{r['added_mass_impulsive'] / r['block_mass']:.2f}; "
            f"{r['added_mass_rigid_lid'] / r['block_mass']:.2f} | {r['wall_s']:.0f} |"
        )
    name.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(CASES))
    parser.add_argument("--fresh", action="store_true")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / "slide_in_water_cpu.json"
    old = [] if args.fresh or not path.exists() else json.loads(path.read_text())
    rows = [r for r in (old["rows"] if old else []) if r["case"] not in args.cases]
    for name in args.cases:
        for c in CASES[name]:
            rows += run(name, c)
            print(f"{name} l0 {c['spacing']} tan {c['tan']} done", flush=True)
    order = list(CASES)
    rows.sort(key=lambda r: order.index(r["case"]))
    write(rows, machine_info())


if __name__ == "__main__":
    main()
