"""A standing wave damped by a porous region over the whole tank, against linear
theory.

With the resistance -u/kappa on every component of the whole fluid, a linear
standing wave obeys eta'' + eta'/kappa + omega0^2 eta = 0: its amplitude decays
at sigma = 1/(2 kappa) faster than without the region, at omega_d^2 = omega0^2 -
1/(4 kappa^2). `standing_wave` (1 m tank, 0.5 m deep) released from rest: the
mode probe is fitted by c + A exp(-sigma t) cos(omega t + phi) (a grid over
sigma and omega, the rest by least squares) over 3 s, for kappa = inf, 1, 0.5,
0.25 s, at two spacings and amplitudes. The added decay sigma(kappa) -
sigma(inf) is compared with 1/(2 kappa); the run without a region measures the
scheme's own (numerical and nonlinear) damping.

Run: python validation/porous_decay.py
(writes results/porous_decay_cpu.{json,md})
"""

import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
KAPPAS = (None, 1.0, 0.5, 0.25)


def fit(t, m):
    """(sigma, omega, amplitude) of c + exp(-sigma t)(a cos + b sin)(omega t)."""
    best = None
    for sigma in np.linspace(0.0, 3.0, 601):
        for omega in np.linspace(5.0, 10.0, 251):
            envelope = np.exp(-sigma * t)
            x = np.stack(
                [
                    np.ones_like(t),
                    envelope * np.cos(omega * t),
                    envelope * np.sin(omega * t),
                ],
                1,
            )
            coef = np.linalg.lstsq(x, m, rcond=None)[0]
            residual = float(np.sum((x @ coef - m) ** 2))
            if best is None or residual < best[0]:
                best = (residual, sigma, omega, float(np.hypot(*coef[1:])))
    return best[1:]


def run(spacing, amplitude, kappa, t_end=3.0):
    settings = dict(spacing=spacing, amplitude=amplitude, dt=0.08 * spacing)
    if kappa is not None:
        settings.update(
            porous_kappa=kappa, porous_box="-1,-1,2,2", porous_direction="all"
        )
    case = jaxmps.scenes.standing_wave(**settings)
    dt = float(case.params.dt)
    every = 5
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
    t = np.asarray(out.saved["time"])
    m = np.asarray(out.saved["mode"])
    sigma, omega, amp = fit(t, m)
    return dict(
        spacing=spacing,
        amplitude=amplitude,
        kappa=kappa,
        dt=dt,
        particles=int(case.state.active.sum()),
        sigma=sigma,
        omega=omega,
        fitted_amplitude=amp,
        result="ok" if out.result == jaxmps.Result.successful else str(out.result),
        wall_s=wall,
    )


def main():
    jax.config.update("jax_enable_x64", True)
    rows = []
    for spacing, amplitude in ((0.025, 0.05), (0.025, 0.025), (0.0125, 0.025)):
        for kappa in KAPPAS:
            rows.append(run(spacing, amplitude, kappa))
            print(rows[-1], flush=True)
    out = dict(machine=machine_info(), rows=rows)
    (HERE / "results" / "porous_decay_cpu.json").write_text(json.dumps(out, indent=1))
    lines = [
        "# Standing wave damped by a porous region over the tank (float64, CPU)",
        "",
        "1 m tank, 0.5 m deep, released from rest; region: whole tank, all",
        "components. sigma: fitted decay rate [1/s]; added = sigma - sigma(no",
        "region); theory 1/(2 kappa). omega: fitted angular frequency; theory",
        "omega_d = sqrt(omega0^2 - 1/(4 kappa^2)) with omega0 of the run without",
        "a region.",
        "",
        "| l0 [m] | A [m] | kappa [s] | sigma | added | 1/(2 kappa) | added / theory "
        "| omega | omega_d theory | wall [s] | result |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        base = next(
            b
            for b in rows
            if b["kappa"] is None
            and (b["spacing"], b["amplitude"]) == (r["spacing"], r["amplitude"])
        )
        if r["kappa"] is None:
            added = theory = ratio = omega_d = "-"
        else:
            added_v = r["sigma"] - base["sigma"]
            theory_v = 1 / (2 * r["kappa"])
            added, theory = f"{added_v:.3f}", f"{theory_v:.3f}"
            ratio = f"{added_v / theory_v:.3f}"
            omega_d = f"{np.sqrt(base['omega'] ** 2 - theory_v**2):.3f}"
        lines.append(
            f"| {r['spacing']} | {r['amplitude']} | {r['kappa'] or 'none'} "
            f"| {r['sigma']:.3f} | {added} | {theory} | {ratio} | {r['omega']:.3f} "
            f"| {omega_d} | {r['wall_s']:.0f} | {r['result']} |"
        )
    lines += ["", f"Machine: {out['machine']}"]
    (HERE / "results" / "porous_decay_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
