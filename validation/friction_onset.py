"""Friction onset and sliding accuracy of the rigid-body Coulomb law, 2-D and 3-D.

For each mu, gravity is tilted to tan(theta) = r mu for several ratios r, all as one
vmapped batch (`jaxmps.sweep`); the block is declared sliding when it moved more than
1 mm in 1 s. The onset then lies between the largest sticking and the smallest
sliding ratio. The sliding distance is compared with g (sin - mu cos) T^2 / 2.

2-D: 1 m block, l0 = 0.1 m, mu = 0.2, 0.4, 0.6, 0.8, r = 0.97, 0.99, 1.01, 1.03, 2.
3-D: 1 m cube, l0 = 0.2 m, mu = 0.5, r = 0.9, 0.95, 1.05, 1.5, 2.
Each without the friction torque (seed 002, the scene's default) and with it
(seed 000: the friction acts at the contact face).

Run: python validation/friction_onset.py  (writes results/friction_onset_cpu.{json,md})
"""

import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
G, T = 9.81, 1.0


def run(dim, mus, ratios, torque, **overrides):
    case = jaxmps.scenes.friction_tilt(dim=dim, friction_torque=torque, **overrides)
    mu = np.repeat(mus, len(ratios))
    ratio = np.tile(ratios, len(mus))
    theta = np.arctan(ratio * mu)
    gravity = np.zeros((len(mu), dim))
    gravity[:, 0], gravity[:, -1] = G * np.sin(theta), -G * np.cos(theta)
    n = round(T / float(case.params.dt))
    start = time.perf_counter()
    res = jaxmps.sweep(
        case,
        {
            "gravity": gravity,
            "rigid.mu_static": mu[:, None],
            "rigid.mu_kinetic": mu[:, None],
        },
        n_steps=n,
        save_every=n // 10,
    )
    wall = time.perf_counter() - start
    dx = np.asarray(res.saved["block_x"])[:, -1] - float(case.state.rigid.centre[0, 0])
    theory = np.maximum(G * (np.sin(theta) - mu * np.cos(theta)), 0) * T**2 / 2
    rows = [
        dict(
            dim=dim,
            torque=torque,
            mu=float(m),
            ratio=float(r),
            distance=float(d),
            theory=float(t),
            result=int(c),
        )
        for m, r, d, t, c in zip(mu, ratio, dx, theory, np.asarray(res.result))
    ]
    return rows, wall


def main():
    jax.config.update("jax_enable_x64", True)
    rows, walls = [], {}
    for torque in (False, True):
        rows2, walls[f"2d_torque_{torque}"] = run(
            2,
            np.array([0.2, 0.4, 0.6, 0.8]),
            np.array([0.97, 0.99, 1.01, 1.03, 2.0]),
            torque,
        )
        rows3, walls[f"3d_torque_{torque}"] = run(
            3,
            np.array([0.5]),
            np.array([0.9, 0.95, 1.05, 1.5, 2.0]),
            torque,
            spacing=0.2,
            # room for the 1.73 m the block slides at 2 mu (on a 3 m floor it ran
            # into the far wall, which read as -14 %)
            floor_length=4.0,
        )
        rows += rows2 + rows3
    out = dict(machine=machine_info(), rows=rows, wall_s=walls)
    (HERE / "results" / "friction_onset_cpu.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Friction onset and sliding distance (float64, CPU)",
        "",
        "| dim | torque | mu | tan(theta)/mu | distance in 1 s [m] | theory [m] | "
        "/ theory | state |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        state = "slides" if r["distance"] > 1e-3 else "sticks"
        share = f"{r['distance'] / r['theory']:.3f}" if r["theory"] > 0 else "-"
        lines.append(
            f"| {r['dim']} | {'on' if r['torque'] else 'off'} | {r['mu']} | "
            f"{r['ratio']} | {r['distance']:.4f} | {r['theory']:.4f} | {share} | "
            f"{state} |"
        )
    lines.append("")
    groups = sorted({(r["dim"], r["torque"], r["mu"]) for r in rows})
    for dim, torque, mu in groups:
        sub = [r for r in rows if (r["dim"], r["torque"], r["mu"]) == (dim, torque, mu)]
        stick = max([r["ratio"] for r in sub if r["distance"] <= 1e-3], default=None)
        slide = min([r["ratio"] for r in sub if r["distance"] > 1e-3], default=None)
        lines.append(
            f"- {dim}-D, torque {'on' if torque else 'off'}, mu = {mu}: onset "
            f"between tan(theta)/mu = {stick} (sticks) and {slide} (slides)"
        )
    (HERE / "results" / "friction_onset_cpu.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
