"""Still water over a bed that is lattice wall on the left and seed 002's packed
grains on the right (grains attached to the bed as walls, T11): is the fluid's
pressure continuous across the junction, with and without the number-density
correction n0 / n_s0 of the grains' pairs (seed 002 eq. 3.73), with the walls'
pressure from the equation of state or from the facing fluid particle
(`Explicit.wall_pressure`), or solved with the fluid's ("solved": the
semi-implicit step, dt = 1 ms)?

A 0.2 m wide tank, 4 l0 of bed under 0.1 m of water, l0 = 5 mm, explicit E-MPS
(c = 10 m/s) or semi-implicit MPS, 1 s; averages over 0.4-1 s, saves every 25
steps. For each half: the pressure of the first fluid layer above the bed and
at mid-depth, as shares of rho g (surface - y), and the standoff of the fluid
from the bed's top row (lowest fluid centre minus the top row's, in l0).

Run: python validation/bed_junction.py  (writes results/bed_junction_cpu.{json,md})
"""

import json
import pathlib
import time

import jax
import numpy as np
from _common import machine_info

import jaxmps
from jaxmps import Kind, geometry

jax.config.update("jax_enable_x64", True)

HERE = pathlib.Path(__file__).parent
L0, WIDTH, ROWS, DEPTH, T = 0.005, 0.2, 4, 0.1, 1.0


def case(correct: bool, wall_pressure: str):
    half, bed_top = WIDTH / 2, ROWS * L0
    walls, wall_kind = geometry.tank([0, 0], [WIDTH, 1.5 * (bed_top + DEPTH)], L0)
    lattice = geometry.block([0, 0], [half, bed_top], L0)
    face = (lattice[:, 1] > bed_top - L0) | (lattice[:, 0] > half - L0)
    lattice_kind = np.where(face, int(Kind.WALL), int(Kind.DUMMY))
    bed = geometry.packed_bed([half, 0], [WIDTH, bed_top], L0)
    fluid = geometry.block([0, bed_top], [WIDTH, bed_top + DEPTH], L0)
    position = np.concatenate([bed, fluid, lattice, walls])
    kind = np.concatenate(
        [np.zeros(len(bed) + len(fluid), np.int32), lattice_kind, wall_kind]
    )
    top = 1.5 * (bed_top + DEPTH)
    domain = ([-0.03, -0.03], [WIDTH + 0.03, top + 0.03])
    if wall_pressure == "solved":  # the semi-implicit solve's walls
        scheme, dt = jaxmps.schemes.standard(), 1e-3
    else:
        solver = jaxmps.Explicit(wall_pressure=wall_pressure)
        scheme, dt = jaxmps.schemes.explicit(solver), 0.4 * L0 / 10.0
    scene = jaxmps.make_scene(position, L0, domain, scheme=scheme)
    params = jaxmps.make_params(2, dt=dt)
    state = jaxmps.make_state(scene, position, kind)
    grains = np.arange(len(position)) < len(bed)
    extra = {"junction_correction": correct}
    scene, params, state = jaxmps.add_grains(
        scene,
        params,
        state,
        grains,
        friction=0.5,
        restitution=0.1,
        density=2650.0,
        attached=grains,
        **extra,
    )
    tops = {"left": bed_top - 0.5 * L0, "right": float(bed[:, 1].max())}
    return scene, params, state, len(bed), len(fluid), tops


def measure(correct: bool, wall_pressure: str) -> dict:
    scene, params, state, m, nf, tops = case(correct, wall_pressure)
    n = int(T / float(params.dt)) // 25 * 25
    start = time.perf_counter()
    run = jaxmps.simulate(scene, params, state, n, 25, throw=False)
    wall = time.perf_counter() - start
    pressure = np.asarray(run.saved.pressure)
    x = np.asarray(run.saved.position)
    late = slice(int(0.4 * pressure.shape[0]), None)
    fluid = np.zeros(pressure.shape[1], bool)
    fluid[m : m + nf] = True
    surface = x[:, fluid, 1].max(axis=1)[late].mean()
    hydrostatic = 1000.0 * 9.81 * (surface - x[..., 1])
    row = {
        "correct": correct,
        "wall_pressure": wall_pressure,
        "ns0_over_n0": scene.grains.packed_density / scene.n0,
        "packing": scene.grains.packing,
        "detached": int((~np.asarray(run.state.grains.attached)).sum()),
        "result": run.result.name if hasattr(run.result, "name") else str(run.result),
        "wall_s": round(wall, 1),
    }
    for side, (a, b) in {"left": (0.03, 0.09), "right": (0.11, 0.17)}.items():
        here = fluid[None, :] & (x[..., 0] > a) & (x[..., 0] < b)
        lowest = np.where(here, x[..., 1], np.inf).min(axis=1)[late].mean()
        first = here & (x[..., 1] < lowest + 1.2 * L0)
        middle = here & (np.abs(x[..., 1] - (tops["left"] + 0.5 * DEPTH)) < 4 * L0)

        def share(mask):
            return float(
                (pressure * mask)[late].sum() / (hydrostatic * mask)[late].sum()
            )

        row[side] = {
            "first_layer_p": round(share(first), 4),
            "mid_depth_p": round(share(middle), 4),
            "standoff_l0": round((lowest - tops[side]) / L0, 3),
        }
    return row


def main() -> None:
    rows = [
        measure(correct, wall)
        for wall in ("equation", "facing", "solved")
        for correct in (True, False)
    ]
    info = machine_info()
    name = HERE / "results" / "bed_junction_cpu"
    name.with_suffix(".json").write_text(
        json.dumps({"machine": info, "rows": rows}, indent=2)
    )
    lines = [
        "# Still water over a lattice / packed-grain bed junction (T11)",
        "",
        f"l0 = {L0} m, {ROWS} l0 of bed, {DEPTH} m of water, explicit E-MPS, "
        f"{T} s, averages over 0.4-1 s; mid-depth: within 4 l0 of half the depth; "
        "wall pressure 'solved': the semi-implicit step (dt = 1 ms). "
        f"Machine: {info.get('cpu_model', '?')} "
        f"(load {info.get('loadavg_1min_start', 0):.1f}).",
        "",
        "| wall pressure | n0/n_s0 correction | n_s0/n0 | side | first layer P / "
        "rho g h | mid-depth P / rho g h | standoff [l0] | detached | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        for side in ("left", "right"):
            s = r[side]
            lines.append(
                f"| {r['wall_pressure']} | {'yes' if r['correct'] else 'no'} | "
                f"{r['ns0_over_n0']:.4f} | "
                f"{side} ({'lattice' if side == 'left' else 'grains'}) | "
                f"{s['first_layer_p']:.3f} | {s['mid_depth_p']:.3f} | "
                f"{s['standoff_l0']:.2f} | {r['detached']} | {r['wall_s']} |"
            )
    (name.with_suffix(".md")).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
