"""Pressure pulses in porous regions with a porosity, step by step, with the
isolated-surface filter counting a region's neighbours by their pore weight (as
built) and one by one (as before).

Still water (`hydrostatic`, 0.4 m x 0.2 m, l0 = 1 cm) with a region of porosity
phi through the whole depth over x = 0.1-0.3 m (kappa = 0.05 s, its water
thinned to phi), 2,000 fixed steps of dt = 1 ms: the mean pressure of the particles
within 2 l0 of the floor in the region's core (x = 0.13-0.27 m) after every step
from the 201st, and the steps on which it is more than 10 % off its median.

A pulse is one particle inside the region taken for free surface (P = 0) for a
step: the pressure around it falls, then overshoots. The filter (Masuda et al.)
keeps an interior particle whose number density dips below beta n0 in the
solve if it has at least `FreeSurface.min_neighbours` neighbours; a region's
sparser water has fewer (at phi = 0.8 about 10 on average, 7 at least, against
14 and 11 in open water), so counted one by one a dip there stayed flagged.
The rows below the default floor (`fluid.lowest_porosity`, 0.81 here) are run
with it lowered.

Run: python validation/porous_pulses.py
(about 6 min on 2 cores; writes results/porous_pulses_cpu.{json,md})
"""

import json
import time

import jax
import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps import Kind, fluid
from jaxmps._step import _step
from jaxmps.fluid import _porous as porous_module

PHIS = (0.9, 0.85, 0.8, 0.75, 0.7)
SCHEMES = ("standard", "standard_ds")
STEPS, SKIPPED = 2000, 200


def pulsing_steps(scheme, phi):
    """Steps on which the core's floor pressure is > 10 % off its median."""
    case = jaxmps.scenes.hydrostatic(
        width=0.4,
        depth=0.2,
        spacing=0.01,
        scheme=scheme,
        dt=0.001,
        porous_kappa=0.05,
        porous_box="0.1,-1,0.3,1",
        porous_direction="all",
        porous_porosity=phi,
    )
    # Fixed steps of params.dt, each run traced afresh (`jaxmps.step` keeps its
    # compiled program for a scene, so it would not see the filter swapped).
    step = jax.jit(lambda s: _step(case.scene, case.params, s)[0])
    water = np.asarray(case.state.kind) == int(Kind.FLUID)
    state, means = case.state, []
    for _ in range(STEPS):
        state = step(state)
        x = np.asarray(state.position)
        core = np.asarray(state.active) & water
        core &= (x[:, 0] > 0.13) & (x[:, 0] < 0.27) & (x[:, 1] < 0.02)
        means.append(np.asarray(state.pressure)[core].mean())
    means = np.asarray(means[SKIPPED:])
    median = np.median(means)
    off = np.abs(means / median - 1) > 0.1
    return dict(
        off=int(off.sum()),
        largest=float(np.abs(means / median - 1).max()),
        result="ok" if state.result == jaxmps.Result.successful else str(state.result),
    )


def main():
    jax.config.update("jax_enable_x64", True)
    porous_module.LEAST_SHARE = 0.6
    as_built = fluid.detect_surface

    def one_by_one(*args):
        return as_built(*args[:7])

    rows = []
    for counting, detect in (("pore weight", as_built), ("one by one", one_by_one)):
        fluid.detect_surface = detect
        for scheme in SCHEMES:
            for phi in PHIS:
                start = time.perf_counter()
                row = dict(counting=counting, scheme=scheme, phi=phi)
                row.update(
                    pulsing_steps(scheme, phi), wall_s=time.perf_counter() - start
                )
                rows.append(row)
                print(row, flush=True)
    fluid.detect_surface = as_built
    record = dict(rows=rows, machine=machine_info())
    (HERE / "results" / "porous_pulses_cpu.json").write_text(
        json.dumps(record, indent=1)
    )
    counted = STEPS - SKIPPED
    lines = [
        "# Pressure pulses in porous regions, step by step (CPU, float64)",
        "",
        "Still water 0.4 x 0.2 m, l0 = 1 cm, a region through the whole depth over "
        f"x = 0.1-0.3 m; {STEPS} steps of 1 ms, the last {counted} counted: steps "
        "on which the mean floor pressure (within 2 l0) of the region's core is more "
        "than 10 % off its median, and the largest |p / median - 1|. The "
        "isolated-surface filter counts a region's neighbours by their pore weight "
        "(as built) or one by one.",
        "",
        "| scheme | phi | pore weight: off | largest | one by one: off | largest |",
        "|---|---|---|---|---|---|",
    ]
    for scheme in SCHEMES:
        for phi in PHIS:
            built, plain = (
                next(
                    r
                    for r in rows
                    if r["scheme"] == scheme and r["phi"] == phi and r["counting"] == c
                )
                for c in ("pore weight", "one by one")
            )
            lines.append(
                f"| {scheme} | {phi} | {built['off']} | {100 * built['largest']:.0f} % "
                f"| {plain['off']} | {100 * plain['largest']:.0f} % |"
            )
    lines += ["", f"Machine: {record['machine']}"]
    (HERE / "results" / "porous_pulses_cpu.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
