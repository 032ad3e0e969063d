"""Pressure along the wetted surface of a floating box at rest against hydrostatics.

`scenes.floating_box` (B = 0.2 m, H = 0.1 m, water 0.2 m deep,
`body_pressure="fluid"`) settles for `--settle` seconds; then, over `--window`
seconds, the pressure of the box's particles is averaged, each followed by its
index (the box is rigid). The reference is rho g (s - z), s the free surface the
pressure sees (the `surface_left/right` probes, `PressureLevel`) and z a height.

A body particle's centre lies l0/2 inside the face, where the model does not hold
the water's pressure. Pressed like the fluid it replaces, the box is solved as a
fluid of its own, lighter density (its dry top held at that density's surface
head); with the default scheme's gradient (the minimum-pressure shift) its bottom
row then reads above the water's hydrostatic value at its centres (for a fluid of
the box's density down to the face, by (rho - rho_b) g l0/2), with the corrected
gradient (`standard_ds`, `high_accuracy`) it does not. Reported, per position
along each wetted face:

- 'centre': the particle's pressure over rho g (s - z_i), z_i its centre;
- 'interface': the bottom row's pressure over rho g (s - z_face) - rho_b g l0/2
  (continuity across the face with a fluid of the box's density inside it);
- 'face': the pressure on the face, extrapolated linearly from the box's first two
  layers (P = 1.5 P_1 - 0.5 P_2), over rho g (s - z_face);
- 'water': the water's first two layers outside the bottom face (in bins of l0
  along it), extrapolated linearly to the face, over rho g (s - z_face); on the
  side faces, the water's first two columns beside each (in bins of l0 of
  height above the keel), extrapolated across to the face, over rho g (s - z),
  z the mean height of the water in the bin;
- 'probe': the scene's `pressure_keel` gauge (`BodyPressure`: the water within
  2 l0 of the bottom face's middle, 1.75 l0 either side, fitted linearly against
  the distance from the face and read there).

Every value is a mean over every step of the window: a few dozen samples alias
the pressure's step-to-step noise (1 s means of 60 samples at B/10 spread by
10 %, and read the water under the box 2 % above hydrostatic; over every step it
is hydrostatic within 0.02 rho g l0).

The explicit solver's pressure is the equation of state's compression: on the
box's rigid lattice its interior carries none (n* = n0), and the bottom row reads
how tightly the water packs against it, not a hydrostatic pressure.

Run: python validation/floating_pressure.py [--cases solver:ratio:l0 ...]
(about 15 min on 2 cores; writes results/floating_pressure_cpu.{json,md})
"""

import argparse
import json
import time

import jax
import jax.numpy as jnp
import numpy as np
from _common import HERE, machine_info

import jaxmps
from jaxmps import Kind


def observe(case, body, bins, rows):
    """Per step: the probes, the box's particles' pressure and position, and, for
    the water under the keel, per bin of l0 along it and per layer of l0 below it,
    the sums of pressure and of depth below the keel and the count; beside each
    side face, per bin of l0 of height above the keel and per column of l0 out
    from the face, the sums of pressure, of distance from the face and of height,
    and the count."""
    probes = jaxmps.scenes.observe_probes(case.probes)
    l0 = case.config["spacing"]
    half = 0.5 * case.config["box_width"]
    body = jnp.asarray(body)

    def fn(scene, state):
        values = probes(scene, state)
        x, z = state.position[:, 0], state.position[:, -1]
        keel = jnp.min(z[body]) - 0.5 * l0
        along = jnp.floor((x - values["box_x"] + half) / l0).astype(jnp.int32)
        below = keel - z
        layer = jnp.floor(below / l0).astype(jnp.int32)
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        take = fluid & (along >= 0) & (along < bins) & (layer >= 0) & (layer < 2)
        cell = jnp.where(take, along * 2 + layer, 2 * bins)

        def sums(v):
            return jax.ops.segment_sum(jnp.where(take, v, 0.0), cell, 2 * bins + 1)[:-1]

        # Beside the side faces: cell (side, height bin, column).
        out_left = values["box_x"] - half - x
        out_right = x - values["box_x"] - half
        out = jnp.maximum(out_left, out_right)
        right = out_right > out_left
        column = jnp.floor(out / l0).astype(jnp.int32)
        height = jnp.floor((z - keel) / l0).astype(jnp.int32)
        beside = fluid & (column >= 0) & (column < 2) & (height >= 0) & (height < rows)
        cell_b = jnp.where(
            beside, (right.astype(jnp.int32) * rows + height) * 2 + column, 4 * rows
        )

        def sums_beside(v):
            return jax.ops.segment_sum(jnp.where(beside, v, 0.0), cell_b, 4 * rows + 1)[
                :-1
            ]

        return {
            "probes": values,
            "body_p": state.pressure[body],
            "body_x": x[body],
            "body_z": z[body],
            "water_p": sums(state.pressure),
            "water_depth": sums(below),
            "water_n": sums(jnp.ones_like(below)),
            "side_p": sums_beside(state.pressure),
            "side_out": sums_beside(out),
            "side_z": sums_beside(z),
            "side_n": sums_beside(jnp.ones_like(out)),
        }

    return fn


def _columns(values, keys, l0):
    """Mean of `values` grouped by `keys` (lattice offsets k or k + 1/2 l0):
    {bin: mean}."""
    bins = np.floor(keys / l0 + 0.25).astype(int)
    return {int(b): float(values[bins == b].mean()) for b in np.unique(bins)}


def _side_rows(p, z, rx, rz, lo, hi, surface, l0, rho_g):
    """The side faces: the box's two outer columns (time means per particle, `rx`
    and `rz` its place in the body), below the water line's layer and above the
    keel's, extrapolated to the face."""
    rows = []
    corner = int(np.floor(lo[-1] / l0 + 0.25))
    for side, edge, step in (("left", lo[0], l0), ("right", hi[0], -l0)):
        col1 = np.isclose(rx, edge)
        col2 = np.isclose(rx, edge + step)
        q1, q2 = _columns(p[col1], rz[col1], l0), _columns(p[col2], rz[col2], l0)
        heights = _columns(z[col1], rz[col1], l0)
        for b, pb in q1.items():
            depth = surface - heights[b]
            if depth < l0 or b == corner:
                continue
            face = 1.5 * pb - 0.5 * q2[b] if b in q2 else pb
            rows.append(
                dict(
                    face=f"side {side}",
                    at=float(depth),
                    centre=pb / (rho_g * depth),
                    interface=None,
                    face_ratio=face / (rho_g * depth),
                )
            )
    return rows


def _water_sides(s, side_bins, surface, l0, rho_g):
    """The water's first two columns beside each side face (time means of the
    observer's sums), extrapolated across to the face, per bin of height."""
    sp, so = (
        s["side_p"].reshape(2, side_bins, 2),
        s["side_out"].reshape(2, side_bins, 2),
    )
    sz, sn = s["side_z"].reshape(2, side_bins, 2), s["side_n"].reshape(2, side_bins, 2)
    rows = []
    for k, side in enumerate(("left", "right")):
        for b in range(side_bins):
            if not np.all(sn[k, b] > 0.5):
                continue
            pm, om = sp[k, b] / sn[k, b], so[k, b] / sn[k, b]
            depth = surface - sz[k, b].sum() / sn[k, b].sum()
            if depth < l0:
                continue
            face = pm[0] - om[0] * (pm[1] - pm[0]) / (om[1] - om[0])
            rows.append(
                dict(
                    face=f"side {side}",
                    at=float(depth),
                    face_ratio=float(face / (rho_g * depth)),
                )
            )
    return rows


def measure(spacing, ratio, solver, settle, window, scheme=None):
    settings = {} if scheme is None else {"scheme": scheme}
    case = jaxmps.scenes.floating_box(
        density_ratio=ratio,
        spacing=spacing,
        body_pressure="fluid",
        solver=solver,
        **settings,
    )
    c, dt, l0 = case.config, float(case.params.dt), spacing
    rho_g = c["density"] * c["gravity"]
    rho_b_g = ratio * rho_g
    body = np.flatnonzero(np.asarray(case.state.rigid.body) >= 0)
    bins = round(c["box_width"] / l0)
    side_bins = round(c["box_height"] / l0)
    n = round(settle / dt)
    start = time.perf_counter()
    first = jaxmps.simulate(case.scene, case.params, case.state, n, n)
    # Every step: a few dozen samples alias the pressure's step-to-step noise
    # (1 s means of 60 samples at B/10 spread by 10 %).
    out = jaxmps.simulate(
        case.scene,
        case.params,
        first.state,
        round(window / dt),
        1,
        observe=observe(case, body, bins, side_bins),
    )
    wall = time.perf_counter() - start
    s = jax.tree.map(lambda a: np.asarray(a).mean(axis=0), out.saved)
    surface = 0.5 * (s["probes"]["surface_left"] + s["probes"]["surface_right"])
    reference = np.asarray(case.state.rigid.reference)[body]
    rx, rz = reference[:, 0], reference[:, -1]
    lo, hi = reference.min(axis=0), reference.max(axis=0)
    p, x, z = s["body_p"], s["body_x"], s["body_z"]
    # The box barely turns at rest (heel below 1 degree): faces in the tank frame
    # from the mean positions.
    z_keel = z[np.isclose(rz, lo[-1])].mean() - 0.5 * l0
    d_keel = surface - z_keel
    rows = []
    # Bottom face: the box's columns.
    row1 = np.isclose(rz, lo[-1])
    row2 = np.isclose(rz, lo[-1] + l0)
    p1, p2 = _columns(p[row1], rx[row1], l0), _columns(p[row2], rx[row2], l0)
    xs = _columns(x[row1], rx[row1], l0)
    zs = _columns(z[row1], rx[row1], l0)
    for b, pb in p1.items():
        face = 1.5 * pb - 0.5 * p2[b] if b in p2 else pb
        rows.append(
            dict(
                face="bottom",
                at=xs[b],
                centre=pb / (rho_g * (surface - zs[b])),
                interface=pb / (rho_g * d_keel - 0.5 * rho_b_g * l0),
                face_ratio=face / (rho_g * d_keel),
            )
        )
    rows += _side_rows(p, z, rx, rz, lo, hi, surface, l0, rho_g)
    # The water's first two layers under the keel, extrapolated to it, per bin.
    wp = s["water_p"].reshape(bins, 2)
    wd = s["water_depth"].reshape(bins, 2)
    wn = s["water_n"].reshape(bins, 2)
    water = []
    for b in range(bins):
        if np.all(wn[b] > 0.5):
            pm, dm = wp[b] / wn[b], wd[b] / wn[b]
            face = pm[0] - dm[0] * (pm[1] - pm[0]) / (dm[1] - dm[0])
            ratio_b = float(face / (rho_g * d_keel))
            water.append(dict(at=(b + 0.5) * l0, face_ratio=ratio_b))
    water_sides = _water_sides(s, side_bins, surface, l0, rho_g)
    return dict(
        solver=solver,
        scheme=scheme or case.config.get("scheme", "standard"),
        spacing=l0,
        box_over_l0=bins,
        density_ratio=ratio,
        draft_l0=float((d_keel - ratio * c["box_height"]) / l0),
        probe=float(s["probes"]["pressure_keel"] / (rho_g * d_keel)),
        steps=round(window / dt),
        result=str(out.result),
        wall_s=wall,
        body=rows,
        water=water,
        water_sides=water_sides,
    )


def summary(m):
    out = {}
    for face, key in (
        ("bottom", "centre"),
        ("bottom", "interface"),
        ("bottom", "face_ratio"),
        ("side", "centre"),
        ("side", "face_ratio"),
    ):
        r = np.array([row[key] for row in m["body"] if row["face"].startswith(face)])
        if len(r):
            out[f"{face} {key}"] = (float(r.mean()), float(r.min()), float(r.max()))
    w = np.array([row["face_ratio"] for row in m["water"]])
    out["water face_ratio"] = (float(w.mean()), float(w.min()), float(w.max()))
    w = np.array([row["face_ratio"] for row in m.get("water_sides", ())])
    if len(w):
        out["water side"] = (float(w.mean()), float(w.min()), float(w.max()))
    out["probe"] = (m["probe"],) * 3
    return out


LABELS = {
    "bottom centre": "bottom row, at its centres",
    "bottom interface": "bottom row, against continuity with rho_b inside",
    "bottom face_ratio": "bottom face, from the box (two layers)",
    "side centre": "side columns, at their centres",
    "side face_ratio": "side faces, from the box (two layers)",
    "water face_ratio": "bottom face, from the water (two layers)",
    "water side": "side faces, from the water (two columns)",
    "probe": "`pressure_keel` gauge (the water at the keel's middle)",
}


def _label(m):
    """The solver, and the scheme where it is not the default."""
    scheme = m.get("scheme", "standard")
    return m["solver"] if scheme == "standard" else f"{m['solver']} ({scheme})"


def _key(m):
    return (m["solver"], m.get("scheme", "standard"), m["density_ratio"], m["spacing"])


def markdown(results, info):
    lines = [
        "# Floating box at rest: pressure along the wetted surface",
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; "
        "`validation/floating_pressure.py`. Each value is a time-mean pressure",
        "over its hydrostatic reference, mean (min .. max) over the positions along",
        "the face; see the script's docstring for the columns. Target: within 2 %.",
        "",
        "| solver | l0 [m] | B/l0 | ratio | draft err [l0] | measure | mean | min |"
        " max |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for m in results:
        for key, (mean, lo, hi) in summary(m).items():
            lines.append(
                f"| {_label(m)} | {m['spacing']} | {m['box_over_l0']} |"
                f" {m['density_ratio']} | {m['draft_l0']:+.2f} | {LABELS[key]} |"
                f" {mean:.3f} | {lo:.3f} | {hi:.3f} |"
            )
    lines.append("")
    for m in results:
        lines.append(
            f"Per position, {_label(m)}, l0 = {m['spacing']} m, ratio"
            f" {m['density_ratio']} (x [m] along the bottom, or depth [m] on a side:"
            " centre / interface / face; water face):"
        )
        lines.append("")
        for row in m["body"]:
            inter = "-" if row["interface"] is None else f"{row['interface']:.3f}"
            lines.append(
                f"- {row['face']} {row['at']:.4f}: {row['centre']:.3f} / {inter} /"
                f" {row['face_ratio']:.3f}"
            )
        lines.append(
            "- water under the bottom: "
            + ", ".join(f"{w['face_ratio']:.3f}" for w in m["water"])
        )
        if m.get("water_sides"):
            lines.append(
                "- water beside the sides (depth [m]: face): "
                + ", ".join(
                    f"{w['face'][5:]} {w['at']:.4f}: {w['face_ratio']:.3f}"
                    for w in m["water_sides"]
                )
            )
        lines.append("")
    return "\n".join(lines) + "\n"


CASES = [
    "semi_implicit:0.5:0.02",
    "semi_implicit:0.5:0.01",
    "semi_implicit:0.5:0.005",
    "semi_implicit:0.3:0.02",
    "semi_implicit:0.3:0.01",
    "semi_implicit:0.8:0.02",
    "semi_implicit:0.8:0.01",
    "semi_implicit:0.5:0.01:standard_ds",
    "semi_implicit:0.5:0.01:high_accuracy",
    "explicit:0.5:0.02",
    "explicit:0.5:0.01",
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases",
        nargs="+",
        default=CASES,
        help="solver:density_ratio:spacing [m][:scheme] (default: the table's matrix)",
    )
    parser.add_argument("--settle", type=float, default=2.0)
    parser.add_argument("--window", type=float, default=1.0)
    parser.add_argument("--name", default="floating_pressure_cpu")
    parser.add_argument(
        "--merge", action="store_true", help="keep the file's rows not re-measured"
    )
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / args.name
    results = []
    for case in args.cases:
        solver, ratio, l0, *scheme = case.split(":")
        m = measure(float(l0), float(ratio), solver, args.settle, args.window, *scheme)
        results.append(m)
        print(json.dumps({"case": case, **summary(m)}), flush=True)
    if args.merge and path.with_suffix(".json").exists():
        new = {_key(m) for m in results}
        old = json.loads(path.with_suffix(".json").read_text())["results"]
        results = [m for m in old if _key(m) not in new] + results
    info = machine_info()
    path.with_suffix(".json").write_text(
        json.dumps({"machine": info, "results": results}, indent=1)
    )
    path.with_suffix(".md").write_text(markdown(results, info))


if __name__ == "__main__":
    main()
