"""Friction on an elastic block against Coulomb's law (seed 000 §2.6 for elastic
bodies; `friction_tilt` with `body="elastic"`).

A 1 m block (E = 1 MPa, nu = 0.3, rho = 1500 kg/m^3, l0 = 0.1 m, 2-D, meeting the
floor by the contact push) is relaxed to rest on the floor under the normal part
of gravity, then gravity is tilted by theta. Over T = 0.5 s: the mean x, the
acceleration a fitted from 0.1 s on and, beyond the onset (tan(theta) > mu), the
floor's friction per unit mass (g sin - a) over mu g cos (1 for a rigid block
sliding by the law). For mu = 0.5: tan(theta) / mu from 0.5 to 2, at the scene's
largest step (adaptive, 0.002 s) and at dt = 2e-4 s; and mu = 0, 0.3 at 35
degrees.

Run: python validation/elastic_friction.py
(writes results/elastic_friction_cpu.{json,md})
"""

import json
import math
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
G, T = 9.81, 0.5
TIMES = np.arange(0.02, T + 1e-9, 0.02)


def run(theta, mu, dt=None):
    overrides = {} if dt is None else {"dt": dt}
    case = jaxmps.scenes.friction_tilt(
        body="elastic", angle=theta, mu_static=mu, **overrides
    )
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=TIMES,
        observe=jaxmps.scenes.observe_probes(case.probes),
        throw=False,
    )
    x = np.asarray(out.saved["block_x"])
    late = TIMES >= 0.1
    basis = np.stack([np.ones(late.sum()), TIMES[late], TIMES[late] ** 2 / 2], 1)
    accel = float(np.linalg.lstsq(basis, x[late], rcond=None)[0][2])
    rad = math.radians(theta)
    theory = max(G * (math.sin(rad) - mu * math.cos(rad)), 0.0)
    moved = float(x[-1] - x[0])
    beyond = mu > 0 and math.tan(rad) > mu
    friction = (
        (G * math.sin(rad) - accel) / (mu * G * math.cos(rad)) if beyond else None
    )
    return dict(
        theta=theta,
        mu=mu,
        ratio=math.tan(rad) / mu if mu > 0 else None,
        dt=float(case.params.dt),
        fixed=dt is not None,
        moved=moved,
        largest=float(np.max(np.abs(x - x[0]))),
        accel=accel,
        theory=theory,
        friction=friction,
        result=str(out.result),
        wall_s=time.perf_counter() - start,
    )


def main():
    jax.config.update("jax_enable_x64", True)
    rows = []
    for dt in (None, 2e-4):
        for ratio in (0.5, 0.8, 0.9, 0.97, 1.03, 1.1, 1.5, 2.0):
            theta = math.degrees(math.atan(ratio * 0.5))
            rows.append(run(theta, 0.5, dt))
            print(rows[-1], flush=True)
        for mu in (0.0, 0.3):
            rows.append(run(35.0, mu, dt))
            print(rows[-1], flush=True)
    out = dict(machine=machine_info(), t_end=T, rows=rows)
    (HERE / "results" / "elastic_friction_cpu.json").write_text(
        json.dumps(out, indent=1)
    )
    lines = [
        "# Elastic block on a tilted floor: friction against Coulomb's law "
        "(float64, CPU)",
        "",
        "1 m block, E = 1 MPa, nu = 0.3, rho = 1500 kg/m^3, l0 = 0.1 m, relaxed to",
        f"rest, then tilted; {T} s. friction = (g sin - a) / (mu g cos) beyond the",
        "onset (a fitted from 0.1 s); 'moved' is the mean x's change, 'largest'",
        "its largest excursion. dt: the scene's largest step (adaptive) or fixed.",
        "",
        "| theta [deg] | mu | tan/mu | dt [s] | moved [m] | largest [m] | a [m/s^2] "
        "| theory | friction / mu N | result |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ratio = "" if r["ratio"] is None else f"{r['ratio']:.2f}"
        friction = "" if r["friction"] is None else f"{r['friction']:.3f}"
        lines.append(
            f"| {r['theta']:.2f} | {r['mu']} | {ratio} | "
            f"{r['dt']:.3g}{'' if r['fixed'] else ' (adaptive)'} | {r['moved']:.4f} "
            f"| {r['largest']:.4f} | {r['accel']:.3f} | {r['theory']:.3f} "
            f"| {friction} | {r['result'].split('<')[-1].rstrip('>') or 'ok'} |"
        )
    lines += ["", f"Machine: {out['machine']}"]
    (HERE / "results" / "elastic_friction_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
