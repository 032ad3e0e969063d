"""Pressure along the wetted surface of a floating box at rest against hydrostatics.

`scenes.floating_box` (B = 0.2 m, H = 0.1 m, density ratio 0.5, water 0.2 m deep,
`body_pressure="fluid"`) settles for `--settle` seconds; then, over `--window`
seconds, the pressure of every particle of the box's outer layer that lies below
the water (its bottom row and the two side columns) is averaged, each particle
followed by its index (the box is rigid), together with its height. The reference
at each particle is rho g (s - z), s the free surface the pressure sees (the
`surface_left/right` probes, `PressureLevel`), z the particle's mean height. The
same is reported for the water particles of the first layer outside the box
(within 1.5 l0 of its faces, averaged by position bins of l0 along the face).

Run: python validation/floating_pressure.py [--spacings 0.02 0.01]
(writes results/floating_pressure_cpu.{json,md})
"""

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps import Kind


def observe(case):
    probes = jaxmps.scenes.observe_probes(case.probes)

    def fn(scene, state):
        return {
            "probes": probes(scene, state),
            "position": state.position,
            "pressure": state.pressure,
            "fluid": jnp.logical_and(state.active, state.kind == int(Kind.FLUID)),
        }

    return fn


def measure(spacing, ratio, settle, window, saves):
    case = jaxmps.scenes.floating_box(
        density_ratio=ratio, spacing=spacing, body_pressure="fluid"
    )
    c, dt, l0 = case.config, float(case.params.dt), spacing
    rho_g = c["density"] * c["gravity"]
    n = round(settle / dt)
    first = jaxmps.simulate(case.scene, case.params, case.state, n, n)
    every = max(1, round(window / dt) // saves)
    fn = observe(case)
    out = jaxmps.simulate(
        case.scene, case.params, first.state, every * saves, every, observe=fn
    )
    s = jax.tree.map(np.asarray, out.saved)
    surface = 0.5 * (s["probes"]["surface_left"] + s["probes"]["surface_right"])
    body = np.flatnonzero(np.asarray(case.state.rigid.body) >= 0)
    reference = np.asarray(case.state.rigid.reference)[body]
    lo, hi = reference.min(axis=0), reference.max(axis=0)
    bottom = np.isclose(reference[:, -1], lo[-1])
    side = np.isclose(reference[:, 0], lo[0]) | np.isclose(reference[:, 0], hi[0])
    x = s["position"][:, body, 0]
    z = s["position"][:, body, -1]
    p = s["pressure"][:, body]
    depth = surface[:, None] - z
    rows = []
    for name, mask in (("bottom", bottom), ("side", side & ~bottom)):
        for i in np.flatnonzero(mask):
            d = depth[:, i].mean()
            if d < 1.0 * l0:  # the water line's particles: no hydrostatic reference
                continue
            rows.append(
                dict(
                    face=name,
                    x=float(x[:, i].mean()),
                    depth=float(d),
                    ratio=float(p[:, i].mean() / (rho_g * d)),
                )
            )
    # The water's first layer under the box's bottom face, in bins of l0 along it.
    centre = s["probes"]["box_x"]
    half = 0.5 * c["box_width"]
    zb = z.min(axis=1)
    fx = s["position"][:, :, 0]
    fz = s["position"][:, :, -1]
    under = (
        s["fluid"]
        & (np.abs(fx - centre[:, None]) < half)
        & (fz < zb[:, None])
        & (fz > zb[:, None] - 1.5 * l0)
    )
    water = []
    rel = fx - centre[:, None]
    for b in np.arange(-half, half, l0):
        m = under & (rel >= b) & (rel < b + l0)
        if not m.any():
            continue
        d = (surface[:, None] - fz)[m]
        water.append(
            dict(
                x=float(b + 0.5 * l0),
                depth=float(d.mean()),
                ratio=float(s["pressure"][m].mean() / (rho_g * d.mean())),
            )
        )
    return dict(
        spacing=l0,
        density_ratio=ratio,
        result=str(out.result),
        body=rows,
        water=water,
    )


def summary(m):
    out = {}
    for face in ("bottom", "side"):
        r = np.array([row["ratio"] for row in m["body"] if row["face"] == face])
        if len(r):
            out[face] = (float(r.mean()), float(r.min()), float(r.max()), len(r))
    w = np.array([row["ratio"] for row in m["water"]])
    w = (float(w.mean()), float(w.min()), float(w.max()), len(w))
    out["water under the bottom"] = w
    return out


def markdown(results, info):
    lines = [
        "# Floating box at rest: pressure along the wetted surface",
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; "
        "`validation/floating_pressure.py`. Ratio = time-mean pressure over",
        "rho g (s - z), s the pressure's free surface; mean (min .. max) over the",
        "particles of each face below the water line's layer.",
        "",
        "| l0 [m] | face | particles | mean ratio | min | max |",
        "|---|---|---|---|---|---|",
    ]
    for m in results:
        for face, (mean, lo, hi, count) in summary(m).items():
            lines.append(
                f"| {m['spacing']} | {face} | {count} | {mean:.3f} | {lo:.3f} |"
                f" {hi:.3f} |"
            )
    lines.append("")
    for m in results:
        lines.append(f"Per position, l0 = {m['spacing']} m (face, x or depth: ratio):")
        lines.append("")
        for row in m["body"]:
            where = (
                f"x={row['x']:.3f}"
                if row["face"] == "bottom"
                else (f"depth={row['depth']:.3f}")
            )
            lines.append(f"- {row['face']} {where}: {row['ratio']:.3f}")
        lines.append("")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacings", nargs="+", type=float, default=[0.02, 0.01])
    parser.add_argument("--ratio", type=float, default=0.5)
    parser.add_argument("--settle", type=float, default=2.0)
    parser.add_argument("--window", type=float, default=1.0)
    parser.add_argument("--saves", type=int, default=100)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    results = []
    for l0 in args.spacings:
        m = measure(l0, args.ratio, args.settle, args.window, args.saves)
        results.append(m)
        print(json.dumps({"spacing": l0, **summary(m)}), flush=True)
    info = machine_info()
    path = HERE / "results" / "floating_pressure_cpu"
    path.with_suffix(".json").write_text(
        json.dumps({"machine": info, "results": results}, indent=1)
    )
    path.with_suffix(".md").write_text(markdown(results, info))


if __name__ == "__main__":
    main()
