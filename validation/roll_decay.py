"""Roll free decay of the ship section of Sundsdal et al. (2025) against its
measured roll period.

The section (B = 0.40 m, D = 0.256 m, bilge radius 0.0512 m, 46.8 kg over
0.586 m; data/sundsdal2025_section.csv) floats at its Archimedes draft in water
`--depth` m deep in a tank `--tank` m long, with the measured centre of gravity
(KG = 0.106 m above the keel) and roll radius of gyration (0.360 B), given to
`scenes.floating_box` as `centre_of_gravity` and `gyration` (the section's own
particles would put G at 0.13 m, for a metacentric height of 0.040 m instead of
the measured 0.0629 m). It is released at rest heeled by `--heel` degrees and
its angle fitted over the first `--fit` seconds with the damped oscillation of
`heave_decay.fit_decay`. Also reported: the period without added inertia,
2 pi sqrt(M k^2 / (rho g A GM)), with GM = KB + BM - KG of the section's
geometry at its draft, so that the share of the hydrodynamic (added) inertia can
be read off. In the experiment the model rolled about an axle through G, free in
heave and held in sway by soft springs (sway period 7.5 s); here it is free in
every direction.

Run: python validation/roll_decay.py [--spacings 0.02 0.01] [--merge]
(writes results/roll_decay_ship_cpu.{json,md}; --merge keeps the rows of the
existing file at the spacings not re-measured)
"""

import argparse

import jax
import numpy as np
from _common import HERE
from heave_decay import (
    _measured,
    _section_case,
    add_decay_arguments,
    fit_decay,
    rollout,
    write_spacings,
)


def hydrostatics(beam, draft, radius, kg):
    """(area, KB, BM, GM) of a rectangle of `beam` x `draft` whose two lower
    corners are rounded with `radius`."""
    corner = (1.0 - 0.25 * np.pi) * radius**2
    # centroid of the corner cut-off above the keel (from the corner itself)
    corner_height = (10.0 - 3.0 * np.pi) / (12.0 - 3.0 * np.pi) * radius
    area = beam * draft - 2 * corner
    kb = (beam * draft * 0.5 * draft - 2 * corner * corner_height) / area
    bm = beam**3 / 12.0 / area
    return area, kb, bm, kb + bm - kg


def measure(spacing, tank, depth, heel, t_end, fit):
    data = _measured()
    kg = data["kg"]
    radius = data["roll_gyration_over_beam"] * data["beam"]
    case, mass, draft = _section_case(
        "ship",
        spacing,
        tank,
        depth,
        0.0,
        t_end,
        heel=heel,
        centre_of_gravity=kg,
        gyration=radius,
    )
    s, wall, result = rollout(case, t_end)
    t, angle = s["time"], np.degrees(s["box_angle"])
    window = t <= fit
    w, zeta, residual = fit_decay(t[window], angle[window])
    c = case.config
    area, kb, bm, gm = hydrostatics(c["box_width"], draft, c["bilge_radius"], kg)
    dry = 2 * np.pi * np.sqrt(mass * radius**2 / (1000.0 * 9.81 * area * gm))
    return dict(
        spacing=spacing,
        tank=tank,
        depth=c["depth"],
        heel=heel,
        particles=int(case.state.active.sum()),
        mass=mass,
        draft=draft,
        kg=kg,
        gyration=radius,
        gm=gm,
        period=2 * np.pi / w,
        period_measured=data["roll_period"],
        period_error=2 * np.pi / w / data["roll_period"] - 1,
        period_without_added_inertia=dry,
        zeta=zeta,
        fit_residual=residual,
        wall_s=wall,
        result=str(result),
        series=dict(
            time=t.tolist(),
            angle_deg=angle.tolist(),
            box_x=s["box_x"].tolist(),
            box_y=s["box_y"].tolist(),
        ),
    )


def markdown(rows, info, args):
    r0 = rows[0]
    lines = [
        "# Roll free decay of a ship section against the measured roll period",
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; `validation/roll_decay.py`"
        f" (tank {args.tank} m, depth {args.depth} m, released at rest heeled"
        f" {args.heel} degrees at the Archimedes draft, fit over the first"
        f" {args.fit} s). Section: Sundsdal et al. 2025"
        " (data/sundsdal2025_section.csv), KG = "
        f"{r0['kg']} m, roll radius of gyration {r0['gyration']:.3f} m, GM ="
        f" {r0['gm']:.4f} m from the section's geometry (measured 0.0629 m);"
        " measured roll period 1.26 s. Without added inertia the period would be"
        f" {r0['period_without_added_inertia']:.3f} s.",
        "",
        "| l0 [m] | particles | period [s] | measured [s] | error | zeta |"
        " fit residual | wall [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['spacing']} | {r['particles']} | {r['period']:.4f} |"
            f" {r['period_measured']:.2f} | {r['period_error']:+.1%} |"
            f" {r['zeta']:.3f} | {r['fit_residual']:.2f} | {r['wall_s']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--heel", type=float, default=5.0)
    add_decay_arguments(parser, tank=4.0, depth=1.0, t_end=4.0, fit=3.5)
    parser.add_argument("--out", help="results file name (roll_decay_ship_cpu)")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / (args.out or "roll_decay_ship_cpu")
    write_spacings(
        path,
        args,
        lambda l0: measure(l0, args.tank, args.depth, args.heel, args.t_end, args.fit),
        markdown,
    )


if __name__ == "__main__":
    main()
