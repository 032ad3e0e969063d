"""Rigid and elastic blocks hitting a wall: how the impulse depends on the time step
(seed 000 §3.2.3, Table 3.2-4).

The seed's 2.5 m block (l0 = 0.1 m, rho = 1000 kg/m^3, no gravity) falls at 1 m/s
onto a fixed floor from 0.1 m above it; the elastic one has E = 1e6 Pa, nu = 0.48.
For each dt the impulse on the floor (integrated over 0.4 s: the contact is over
by 0.27 s) and the body's momentum change M (v_end + 1) are divided by those at
dt = 1e-4 s. The floor's force (`WallForce`) is its wall pressure summed over the
contact face and the contact push's reaction (the rigid block's push, and the
elastic block's with `contact="push"`, its default, which leaves the wall
pairs out of the pressure). The elastic runs take one elastic sub-step per step
(the seed's scheme, `substeps=1`), so dt = 1e-2 s is refused; it is then run
with the automatic sub-steps. Also: the block's largest kinetic energy after it
first touches, over the one it came with (at most 1 for a passive contact).

Seed (impulse ratio to dt = 1e-4 s):
    dt      rigid  elastic
    2e-4    1.55   1.14
    5e-4    2.21   1.09
    1e-3    2.45   1.07
    1e-2    2.23   (unstable)

Run: python validation/block_impact.py  (writes results/block_impact_cpu.{json,md})
"""

import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
T_END = 0.4
SEED = {
    "rigid": {2e-4: 1.55, 5e-4: 2.21, 1e-3: 2.45, 1e-2: 2.23},
    "elastic": {2e-4: 1.14, 5e-4: 1.09, 1e-3: 1.07},
}


def run(body, dt, **overrides):
    case = jaxmps.scenes.block_impact(body=body, dt=dt, t_end=T_END, **overrides)
    n = round(T_END / dt)
    probes = jaxmps.scenes.observe_probes(case.probes)

    def observe(scene, state):
        moving = state.velocity if state.elastic is None else state.elastic.velocity
        member = (
            state.rigid.body >= 0
            if state.elastic is None
            else jax.numpy.ones(moving.shape[0], bool)
        )
        energy = jax.numpy.sum(jax.numpy.where(member[:, None], moving**2, 0.0))
        return {**probes(scene, state), "energy": energy}

    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        n_steps=n,
        save_every=1,
        observe=observe,
        throw=False,
    )
    wall = time.perf_counter() - start
    force = np.asarray(out.saved["wall_force"])
    velocity = np.asarray(out.saved["block_velocity_y"])
    mass = case.config["density"] * case.config["block_size"] ** 2
    t = dt * np.arange(1, n + 1)
    touching = t[force > 0]
    energy = np.asarray(out.saved["energy"])
    return dict(
        body=body,
        model=None if case.scene.elastic is None else case.scene.elastic.contact,
        energy=float(np.nanmax(energy) / energy[0]),
        dt=dt,
        substeps=None if case.scene.elastic is None else case.scene.elastic.substeps,
        result="ok"
        if out.result == jaxmps.Result.successful
        else str(out.result).split(":")[0].split("<")[-1],
        # the pressure on the floor comes in spikes one step long: its mean over
        # 5 ms is the force a gauge would read
        smoothed_peak=float(
            np.convolve(force, np.ones(max(1, round(5e-3 / dt))), "valid").max()
            / max(1, round(5e-3 / dt))
        ),
        wall_impulse=float(force.sum() * dt),
        body_impulse=float(mass * (velocity[-1] + 1.0)),
        peak_force=float(force.max()),
        rebound=float(velocity[-1]),
        contact=[float(touching.min()), float(touching.max())]
        if touching.size
        else None,
        wall_s=wall,
    )


def refusal(dt):
    try:
        jaxmps.scenes.block_impact(body="elastic", dt=dt, substeps=1)
    except ValueError as error:
        return str(error)
    return None


def main():
    jax.config.update("jax_enable_x64", True)
    rows = []
    for dt in (1e-4, 2e-4, 5e-4, 1e-3, 1e-2, 2e-2, 5e-2):
        rows.append(run("rigid", dt))
        print(rows[-1], flush=True)
    for contact in ("push", "pressure"):
        for dt in (1e-4, 2e-4, 5e-4, 1e-3):
            rows.append(run("elastic", dt, substeps=1, contact=contact))
            print(rows[-1], flush=True)
    rows.append(run("elastic", 1e-2))
    print(rows[-1], flush=True)
    refused = refusal(1e-2)
    for row in rows:
        base = next(
            r
            for r in rows
            if r["body"] == row["body"]
            and r["model"] == row["model"]
            and r["dt"] == 1e-4
        )
        row["wall_ratio"] = row["wall_impulse"] / base["wall_impulse"]
        row["body_ratio"] = row["body_impulse"] / base["body_impulse"]
        row["seed_ratio"] = SEED[row["body"]].get(row["dt"])
    out = dict(machine=machine_info(), t_end=T_END, rows=rows, refusal=refused)
    (HERE / "results" / "block_impact_cpu.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Block impact: impulse against the time step (float64, CPU)",
        "",
        "Seed 000 §3.2.3: 2.5 m block, l0 = 0.1 m, 1 m/s onto a floor, no gravity;",
        "elastic E = 1e6 Pa, nu = 0.48. Impulses [kN s/m] over 0.4 s and their ratio",
        "to dt = 1e-4 s; momentum bounds 6.25 (plastic) .. 12.5 (elastic rebound).",
        "",
        "| body | contact | dt [s] | sub-steps | wall impulse | ratio | body impulse "
        "| ratio | seed ratio | peak force [kN/m] | over 5 ms | rebound [m/s] "
        "| largest energy | in contact [s] | result |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        seed = "" if r["seed_ratio"] is None else f"{r['seed_ratio']:.2f}"
        contact = (
            ""
            if r["contact"] is None
            else f"{r['contact'][0]:.3f}-{r['contact'][1]:.3f}"
        )
        lines.append(
            f"| {r['body']} | {r['model'] or ''} | {r['dt']:g} "
            f"| {r['substeps'] or ''} "
            f"| {r['wall_impulse'] / 1e3:.2f} | {r['wall_ratio']:.2f} "
            f"| {r['body_impulse'] / 1e3:.2f} | {r['body_ratio']:.2f} | {seed} "
            f"| {r['peak_force'] / 1e3:.0f} | {r['smoothed_peak'] / 1e3:.0f} "
            f"| {r['rebound']:.3f} | {r['energy']:.2f} | {contact} "
            f"| {r['result']} |"
        )
    lines += ["", f"Elastic, dt = 1e-2 s with `substeps=1`: {refused}", ""]
    lines.append(f"Machine: {out['machine']}")
    (HERE / "results" / "block_impact_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
