"""A PMS block sliding down another, dry: does it follow g (sin - mu cos) once the
contact between the two bodies' lattices is rough?

`block_stack` with one block on a wide base block (mu = 2 against the floor, so
the base stays), under gravity tilted to tan(theta); after the scene's settling
(held by mu = 2) the top block gets `mu` against the base and slides from rest.
Per case: its travel along the slope at 0.25 and 0.5 s against
g (sin - mu cos) t^2 / 2 (no air, no water), and the largest normal speed
(hop) and spin (rock) it picks up on the way, and how far it leaned in the
settling (tilt at release).

Cases: l0 = 0.05 and 0.025 m; top blocks 0.5 x 0.25, 0.3 x 0.3 and 0.6 x 0.15 m
(width x height) on a base of the same height, 3 m wide; tan(theta) = 0.6 and
0.9; mu = 0 and 0.3; dt = 1 ms. `--label` names the code measured (rows are
keyed by it, so one file holds runs of two versions of the contact).

Run: python validation/block_slide.py [--label faces] [--spacings 0.05 0.025]
     [--tans 0.6 0.9] [--mus 0 0.3]
     (writes results/block_slide_cpu.{json,md}, merging rows of other labels)
"""

import argparse
import itertools
import json
import math
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps._result import result_name

G = 9.81
SHAPES = {"0.5 x 0.25": (0.5, 0.25), "0.3 x 0.3": (0.3, 0.3), "0.6 x 0.15": (0.6, 0.15)}
TIMES = (0.25, 0.5)


def measure(spacing: float, shape: str, tan: float, mu: float) -> dict:
    width, height = SHAPES[shape]
    case = jaxmps.scenes.block_stack(
        block_size=width,
        block_height=height,
        base_width=3.0,
        floor_length=4.0,
        spacing=spacing,
        dt=0.001,
        mu_static=2.0,
        angle=math.degrees(math.atan(tan)),
    )
    mus = jnp.asarray([2.0, mu], case.params.rigid.mu_static.dtype)
    params = eqx.tree_at(
        lambda p: (p.rigid.mu_static, p.rigid.mu_kinetic), case.params, (mus, mus)
    )
    return _slide(case.scene, params, case.state, tan, mu) | dict(
        spacing=spacing, shape=shape, tan=tan, mu=mu
    )


def _slide(scene, params, state, tan: float, mu: float) -> dict:
    """Run body 1 sliding on body 0 for max(TIMES) s: its travel over theory, hop,
    rock and tilt at release."""
    dim = state.position.shape[-1]

    def observe(scene, state):
        r = state.rigid
        return dict(
            x=r.centre[:, 0],
            v=r.velocity[1],
            w=r.angular_velocity[1],
        )

    steps = round(max(TIMES) / 1e-3)
    start = time.perf_counter()
    out = jaxmps.simulate(scene, params, state, steps, 1, observe=observe)
    wall = time.perf_counter() - start
    saved = {k: np.asarray(v) for k, v in out.saved.items()}
    x = saved["x"] - np.asarray(state.rigid.centre)[None, :, 0]
    theta = math.atan(tan)
    accel = G * (math.sin(theta) - mu * math.cos(theta))
    row = dict(
        result=result_name(out.result),
        particles=int(np.asarray(state.active).sum()),
        wall_s=round(wall, 1),
        base_moved_mm=float(np.abs(x[:, 0]).max() * 1e3),
        tilt_at_release_deg=_tilt_deg(np.asarray(state.rigid.orientation)[1]),
        hop=float(np.abs(saved["v"][:, dim - 1]).max()),
        rock=float(np.abs(saved["w"]).max()),
    )
    for t in TIMES:
        k = round(t / 1e-3) - 1
        row[f"ratio_{t}"] = float(x[k, 1] / (accel * t * t / 2))
    return row


def measure_3d(spacing: float, tan: float, mu: float) -> dict:
    """The 3-D case (`block_stack` is 2-D): a 0.4 x 0.4 x 0.2 m block on a 2 x 1 x
    0.2 m base in a walled box, both of twice the water's density, released at
    once (no settling) under gravity tilted to tan(theta) in x."""
    from jaxmps import geometry

    base = geometry.block([0.1, 0.1, 0.0], [2.1, 1.1, 0.2], spacing)
    top = geometry.block([0.3, 0.4, 0.2], [0.7, 0.8, 0.4], spacing)
    walls, kinds = geometry.tank([0.0, 0.0, 0.0], [2.2, 1.2, 0.6], spacing, layers=3)
    position = np.concatenate([base, top, walls])
    kind = np.r_[np.zeros(len(base) + len(top), int), kinds]
    scene = jaxmps.make_scene(position, spacing, ([-0.4] * 3, [2.6, 1.6, 1.0]))
    theta = math.atan(tan)
    gravity = jnp.asarray([G * math.sin(theta), 0.0, -G * math.cos(theta)])
    params = eqx.tree_at(lambda p: p.gravity, jaxmps.make_params(3, dt=1e-3), gravity)
    state = jaxmps.make_state(scene, position, kind)
    owner = np.r_[
        np.zeros(len(base), int), np.ones(len(top), int), np.full(len(walls), -1)
    ]
    scene, params, state = jaxmps.add_rigid_bodies(
        scene, params, state, owner, density=[2000.0, 2000.0], mu_static=[2.0, mu]
    )
    return _slide(scene, params, state, tan, mu) | dict(
        spacing=spacing, shape="0.4 x 0.4 x 0.2 (3-D)", tan=tan, mu=mu
    )


def table(rows: list[dict]) -> str:
    lines = [
        "| code | l0 [m] | block | tan | mu | travel / theory at 0.25 s | at 0.5 s |"
        " hop [m/s] | rock [rad/s] | tilt at release [deg] | base moved [mm] |"
        " wall [s] | host |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['label']} | {r['spacing']} | {r['shape']} | {r['tan']} | {r['mu']} "
            f"| {r['ratio_0.25']:.3f} | {r['ratio_0.5']:.3f} | {r['hop']:.3f} "
            f"| {r['rock']:.3f} | {_tilt(r)} | {r['base_moved_mm']:.2f} "
            f"| {r['wall_s']:.0f} | {r.get('host', _OLD_HOST)} |"
        )
    return "\n".join(lines)


# Rows written before each row named its host were all run on this one.
_OLD_HOST = "Intel(R) Xeon(R) Processor, family 6 model 167"


def _tilt_deg(orientation: np.ndarray) -> float:
    """The angle turned from the start: the 2-D angle, or the 3-D quaternion's."""
    if orientation.shape[-1] == 1:
        return float(np.degrees(abs(orientation[0])))
    return float(np.degrees(2 * np.arccos(min(1.0, abs(orientation[0])))))


def _tilt(row: dict) -> str:
    tilt = row.get("tilt_at_release_deg")
    return "" if tilt is None else f"{tilt:.2f}"


def _key(row: dict) -> tuple:
    return (row["label"], -row["spacing"], row["shape"], row["tan"], row["mu"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", default="faces")
    parser.add_argument("--spacings", nargs="+", type=float, default=[0.05, 0.025])
    parser.add_argument("--shapes", nargs="+", default=list(SHAPES))
    parser.add_argument("--tans", nargs="+", type=float, default=[0.6, 0.9])
    parser.add_argument("--mus", nargs="+", type=float, default=[0.0, 0.3])
    parser.add_argument("--three-d", action="store_true", help="the 3-D case only")
    parser.add_argument("--out", default="block_slide_cpu")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / args.out
    old = []
    if path.with_suffix(".json").exists():
        old = json.loads(path.with_suffix(".json").read_text())["rows"]
    rows = {_key(r): r for r in old}
    shapes = [None] if args.three_d else args.shapes
    info = machine_info()
    host = info["cpu_model"].replace(", avx512f", "")
    for spacing, shape, tan, mu in itertools.product(
        args.spacings, shapes, args.tans, args.mus
    ):
        if shape is None:
            row = {"label": args.label, **measure_3d(spacing, tan, mu)}
        else:
            row = {"label": args.label, **measure(spacing, shape, tan, mu)}
        row["host"] = host
        print(json.dumps(row), flush=True)
        rows[_key(row)] = row
        every = sorted(rows.values(), key=lambda r: _key(r)[1:] + _key(r)[:1])
        path.with_suffix(".json").write_text(
            json.dumps({"machine": info, "rows": every}, indent=1)
        )
        path.with_suffix(".md").write_text(
            "# A block sliding down another (dry, `block_stack`)\n\n"
            f"Machine of the last run: {info['cpu_model']}, {info['cpu_count']} "
            "cores (each row names its host); float64; "
            "`validation/block_slide.py`. Travel of the top block along the slope "
            "over g (sin - mu cos) t^2 / 2; hop: its largest speed normal to the "
            "base; rock: its largest spin. Codes: `central` pushed each pair of "
            "the two bodies closer than l0 along the pair; `faces` pushes each "
            "particle along the bodies' faces (`_pair_gaps`); `faces + couples` "
            "adds the faces' couples against turning over each other "
            "(`_FacesBetween`).\n\n" + table(every) + "\n"
        )


if __name__ == "__main__":
    main()
