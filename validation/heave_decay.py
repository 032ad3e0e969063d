"""Heave free decay of a floating section against linear potential-flow theory and,
for a ship section, a measured decay test.

`--section box`: `scenes.floating_box` (B = 0.2 m, H = 0.1 m, density ratio 0.5, so
B/T = 4). `--section ship`: the ship section of Sundsdal et al. (2025; B = 0.40 m,
D = 0.256 m, bilge radius 0.0512 m, 46.8 kg over 0.586 m, water 1.0 m deep;
data/sundsdal2025_section.csv), a box with rounded bilges (`bilge_radius`) of
uniform density, whose measured heave decay period is 1.17 s. Either floats in a
tank `--tank` m long and `--depth` m deep (long, so that the radiated waves return
from the end walls only after the fit window) and is released `--offset` m below its
Archimedes draft. The centre's height is fitted over the first `--fit` seconds with
y = c + exp(-zeta w t) (a cos(w_d t) + b sin(w_d t)), w_d = w sqrt(1 - zeta^2)
(`jaxmps.calibration.fit_damped_oscillation`: a grid over w and the decay
rate refined twice, linear least squares for a, b, c). Theory
(`_heave_theory.py`, the rectangle of the same beam and draft): w_n of
w^2 (m + a33(w)) = rho g B and the radiation damping ratio b33 / (2 (m + a33) w_n)
at the same depth.

`--twin` also runs the section released at its Archimedes draft (offset 0): its own
motion (the model's settling to its equilibrium and the particle fluid's noise) is
what the decay cannot be read below; subtracted from the run, the rest is compared
with the theory again.

Run: python validation/heave_decay.py [--section box|ship] [--spacings 0.02 0.01]
[--merge] [--scheme standard_ds] [--variable-density] [--twin] [--out NAME]
(writes results/heave_decay_cpu.{json,md}, or heave_decay_ship_cpu.*; --merge
keeps the rows of the existing file at the spacings not re-measured)
"""

import argparse
import functools
import json
import time

import jax
import numpy as np
from _common import HERE, machine_info
from _heave_theory import free_decay, free_heave

import jaxmps
from jaxmps.calibration import fit_damped_oscillation


def fit_decay(t, y):
    """(w_n [rad/s], zeta, rms residual / amplitude) of the damped oscillation
    c + exp(-zeta w_n t) (a cos w_d t + b sin w_d t), w_d = w_n sqrt(1 - zeta^2),
    closest to y(t): `jaxmps.calibration.fit_damped_oscillation` over periods of
    0.39-1.57 s (w 4-16 rad/s), its damped frequency and decay rate turned into
    the natural frequency and damping ratio."""
    period, ratio, rms = fit_damped_oscillation(t, y, 2 * np.pi / 10.0, spread=0.6)
    w_d = 2 * np.pi / period
    decay = ratio * w_d
    e = np.exp(-decay * t)
    basis = np.stack([np.ones_like(t), e * np.cos(w_d * t), e * np.sin(w_d * t)], 1)
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    w = np.hypot(w_d, decay)
    return w, decay / w, rms / np.hypot(coef[1], coef[2])


# The sections: the box of the theory comparison, and the ship section of
# Sundsdal et al. (data/sundsdal2025_section.csv), whose uniform density gives the
# measured displacement (46.8 kg over 0.586 m) whatever the particles' count.
SECTIONS = {
    "box": dict(box_width=0.2, box_height=0.1, bilge_radius=0.0, mass=10.0),
    "ship": dict(box_width=0.4, box_height=0.256, bilge_radius=0.0512, mass=None),
}


def _measured():
    """The quantities of data/sundsdal2025_section.csv by name."""
    lines = (HERE / "data" / "sundsdal2025_section.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines if line and not line.startswith("#")]
    return {name: float(value) for name, value, _ in rows[1:]}


def _section_case(section, spacing, tank, depth, offset, t_end, **settings):
    """The floating section released `offset` below its Archimedes draft (and
    with further `floating_box` settings), its mass per unit length [kg/m] and
    its Archimedes draft [m]."""
    geometry = dict(SECTIONS[section])
    mass = geometry.pop("mass")
    if mass is None:
        data = _measured()
        mass = data["displacement"] / data["length_across"]
    area = geometry["box_width"] * geometry["box_height"]
    common = dict(spacing=spacing, tank_length=tank, depth=depth, t_end=t_end)
    trial = jaxmps.scenes.floating_box(
        density_ratio=mass / (1000.0 * area), **geometry, **common
    )
    particles = int(np.sum(np.asarray(trial.state.rigid.body) >= 0))
    ratio = mass / (1000.0 * particles * spacing**2)
    r = geometry["bilge_radius"]
    corners = (2.0 - 0.5 * np.pi) * r**2
    draft = (mass / 1000.0 + corners) / geometry["box_width"]
    case = jaxmps.scenes.floating_box(
        density_ratio=ratio,
        initial_draft=draft + offset,
        **geometry,
        **common,
        **settings,
    )
    return case, mass, draft


def echo_time(tank, beam, depth):
    """When the fastest radiated waves (long waves, sqrt(g h)) that left the body's
    sides at release are back at them from the tank's end walls [s]."""
    return (tank - beam) / np.sqrt(9.81 * depth)


def observe_probes_at_start(case):
    """The case's probes in its initial state."""
    return jaxmps.scenes.observe_probes(case.probes)(case.scene, case.state)


def rollout(case, t_end):
    """The case's probes saved every 0.01 s to `t_end` (as arrays), the wall time
    [s] and the run's result."""
    dt = float(case.params.dt)
    saves = round(t_end / 0.01)
    every = max(1, round(t_end / dt) // saves)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        every * saves,
        every,
        observe=jaxmps.scenes.observe_probes(case.probes),
    )
    wall = time.perf_counter() - start
    return {k: np.asarray(v) for k, v in out.saved.items()}, wall, out.result


def measure(
    section,
    spacing,
    tank,
    depth,
    offset,
    t_end,
    fit,
    scheme="standard",
    variable_density=False,
    twin=False,
):
    case, mass, draft = _section_case(
        section,
        spacing,
        tank,
        depth,
        offset,
        t_end,
        scheme=scheme,
        variable_density=variable_density,
    )
    s, wall, result = rollout(case, t_end)
    t, y = s["time"], s["box_y"]
    window = t <= fit
    w, zeta, residual = fit_decay(t[window], y[window])
    c = case.config
    # Linear theory for the rectangle of the same beam and draft (the ship
    # section's bilges are left out of it).
    w_th, zeta_th, added = free_heave(c["box_width"], draft, c["depth"])
    measured = _measured()["heave_period"] if section == "ship" else None
    # The same decay in linear theory (no walls), compared and fitted alike over
    # the time before the first long waves return from the end walls.
    y0 = float(observe_probes_at_start(case)["box_y"])
    y_th = y0 + offset * (1.0 - free_decay(c["box_width"], draft, c["depth"], t))
    free = t <= echo_time(tank, c["box_width"], c["depth"])
    w_free, zeta_free, _ = fit_decay(t[free], y[free])
    w_th_free, zeta_th_free, _ = fit_decay(t[free], y_th[free])
    rms = float(np.sqrt(np.mean((y[free] - y_th[free]) ** 2)) / offset)
    extra = {}
    if twin:
        still, *_ = _section_case(
            section,
            spacing,
            tank,
            depth,
            0.0,
            t_end,
            scheme=scheme,
            variable_density=variable_density,
        )
        s_still, wall_still, _ = rollout(still, t_end)
        own = s_still["box_y"] - float(observe_probes_at_start(still)["box_y"])
        late = free & (t >= 0.5 * t[free][-1])
        extra = dict(
            # the twin's motion about its release height, over the offset
            twin_rms=float(np.sqrt(np.mean(own[free] ** 2)) / offset),
            twin_late_range=float(np.ptp(own[late]) / offset),
            # the run less its twin's motion against the theory
            rms_vs_theory_less_twin=float(
                np.sqrt(np.mean((y[free] - own[free] - y_th[free]) ** 2)) / offset
            ),
            rms_vs_theory_late=float(
                np.sqrt(np.mean((y[late] - y_th[late]) ** 2)) / offset
            ),
            rms_vs_theory_less_twin_late=float(
                np.sqrt(np.mean((y[late] - own[late] - y_th[late]) ** 2)) / offset
            ),
            twin_wall_s=wall_still,
        )
    return dict(
        section=section,
        scheme=scheme,
        variable_density=variable_density,
        mass=mass,
        draft=draft,
        period_measured=measured,
        spacing=spacing,
        tank=tank,
        depth=c["depth"],
        particles=int(case.state.active.sum()),
        period=2 * np.pi / w,
        zeta=zeta,
        fit_residual=residual,
        period_theory=2 * np.pi / w_th,
        zeta_theory=zeta_th,
        added_mass_over_mass=added,
        period_error=(w_th / w) - 1,
        echo_time=echo_time(tank, c["box_width"], c["depth"]),
        period_early=2 * np.pi / w_free,
        zeta_early=zeta_free,
        period_theory_early=2 * np.pi / w_th_free,
        zeta_theory_early=zeta_th_free,
        rms_vs_theory=rms,
        release_y=y0,
        release_offset=offset,
        wall_s=wall,
        result=str(result),
        **extra,
        series=dict(
            time=t.tolist(),
            box_y=y.tolist(),
            theory_y=y_th.tolist(),
            box_x=s["box_x"].tolist(),
            box_angle=s["box_angle"].tolist(),
            level_left=s["level_left"].tolist(),
        ),
    )


def markdown(rows, info, args):
    lines = [
        f"# Heave free decay of a floating section ({args.section}) against"
        " potential-flow theory"
        + (" and the measured period" if args.section == "ship" else ""),
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; `validation/heave_decay.py"
        f" --section {args.section}` (tank {args.tank} m, depth {args.depth} m,"
        f" released {args.offset} m below the Archimedes draft, fit over the first"
        f" {args.fit} s, scheme {args.scheme}"
        + (", `variable_density`" if args.variable_density else "")
        + "). Theory: the rectangle of the same"
        " beam and draft"
        " (`_heave_theory.py`)"
        + (
            "; measured: Sundsdal et al. 2025 (data/sundsdal2025_section.csv),"
            " whose section has bilges of radius 0.0512 m."
            if args.section == "ship"
            else "."
        ),
        "",
        "| l0 [m] | particles | period [s] | theory [s] | error | measured [s] |"
        " error | zeta | zeta, radiation only | fit residual | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        measured = r["period_measured"]
        vs = (
            ("", "")
            if measured is None
            else (f"{measured:.3f}", f"{r['period'] / measured - 1:+.1%}")
        )
        lines.append(
            f"| {r['spacing']} | {r['particles']} | {r['period']:.4f} |"
            f" {r['period_theory']:.4f} | {r['period'] / r['period_theory'] - 1:+.1%} |"
            f" {vs[0]} | {vs[1]} |"
            f" {r['zeta']:.3f} | {r['zeta_theory']:.3f} | {r['fit_residual']:.2f} |"
            f" {r['wall_s']:.0f} |"
        )
    early = [r for r in rows if "period_theory_early" in r]
    if early:
        lines += [
            "",
            f"Before the echo (t <= {early[0]['echo_time']:.2f} s, when long waves"
            " radiated at the release are back from the end walls): the run and the"
            " linear-theory decay of the rectangle in open water (the Cummins decay of"
            " `_heave_theory.free_decay`, from the same release) fitted alike, and"
            " their rms difference over that time as a fraction of the offset. The"
            " theory's own fit differs from its natural period: a33 and b33 vary"
            " with frequency, so its decay is no single damped cosine.",
            "",
            "| l0 [m] | period [s] | theory, fitted [s] | error | zeta | theory,"
            " fitted | rms difference / offset |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in early:
            lines.append(
                f"| {r['spacing']:.4g} | {r['period_early']:.4f} |"
                f" {r['period_theory_early']:.4f} |"
                f" {r['period_early'] / r['period_theory_early'] - 1:+.1%} |"
                f" {r['zeta_early']:.3f} | {r['zeta_theory_early']:.3f} |"
                f" {r['rms_vs_theory']:.3f} |"
            )
    twins = [r for r in early if "twin_rms" in r]
    if twins:
        lines += [
            "",
            "The twin released at its Archimedes draft (offset 0): its own motion"
            " about its release height (rms over the time before the echo, and its"
            " range over that time's second half), and the rms difference of the"
            " run from the theory with the twin's motion subtracted, over the whole"
            " time before the echo and over its second half; all over the offset.",
            "",
            "| l0 [m] | twin rms | twin range, 2nd half | run - theory |"
            " run - twin - theory | run - theory, 2nd half |"
            " run - twin - theory, 2nd half |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in twins:
            lines.append(
                f"| {r['spacing']:.4g} | {r['twin_rms']:.3f} |"
                f" {r['twin_late_range']:.3f} | {r['rms_vs_theory']:.3f} |"
                f" {r['rms_vs_theory_less_twin']:.3f} |"
                f" {r['rms_vs_theory_late']:.3f} |"
                f" {r['rms_vs_theory_less_twin_late']:.3f} |"
            )
    return "\n".join(lines) + "\n"


def plot(rows, path, offset):
    """The runs' heave against the linear-theory decay, as displacement from
    the Archimedes height over the release `offset`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.6))
    shown = [r for r in rows if "theory_y" in r.get("series", {})]
    for r in shown:
        t = np.asarray(r["series"]["time"])
        y = np.asarray(r["series"]["box_y"])
        ax.plot(
            t, (y - r["release_y"]) / offset - 1, label=f"l0 = {r['spacing']:.3g} m"
        )
    if shown:
        r = shown[-1]
        t = np.asarray(r["series"]["time"])
        y = np.asarray(r["series"]["theory_y"])
        ax.plot(
            t,
            (y - r["release_y"]) / offset - 1,
            "k--",
            label="linear theory, open water",
        )
        ax.axvline(r["echo_time"], color="0.6", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("heave / offset")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def add_decay_arguments(parser, tank, depth, t_end, fit):
    """The options both decay scripts take, with their defaults."""
    parser.add_argument("--spacings", nargs="+", type=float, default=[0.02, 0.01])
    parser.add_argument("--tank", type=float, default=tank)
    parser.add_argument("--depth", type=float, default=depth)
    parser.add_argument("--t-end", type=float, default=t_end)
    parser.add_argument("--fit", type=float, default=fit)
    parser.add_argument(
        "--merge",
        action="store_true",
        help="keep the rows of the existing results at spacings not re-measured",
    )


def write_spacings(path, args, measure_row, markdown):
    """Measure `measure_row(l0)` at each of `args.spacings` and write the rows,
    with those of the existing file at other spacings when `args.merge`, to
    `path` .json and .md (`markdown(rows, info, args)`), coarsest first."""
    rows = []
    if args.merge and path.with_suffix(".json").exists():
        old = json.loads(path.with_suffix(".json").read_text())["rows"]
        rows = [r for r in old if r["spacing"] not in args.spacings]
    for l0 in args.spacings:
        row = measure_row(l0)
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "series"}), flush=True)
    rows.sort(key=lambda r: -r["spacing"])
    info = machine_info()
    path.with_suffix(".json").write_text(
        json.dumps({"machine": info, "args": vars(args), "rows": rows}, indent=1)
    )
    path.with_suffix(".md").write_text(markdown(rows, info, args))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--section", choices=sorted(SECTIONS), default="box")
    parser.add_argument("--offset", type=float, default=0.01)
    add_decay_arguments(parser, tank=3.0, depth=0.4, t_end=3.0, fit=2.5)
    parser.add_argument("--scheme", default="standard", help="a scene's scheme setting")
    parser.add_argument(
        "--variable-density",
        action="store_true",
        help="the PPE's pairs weighed by the bodies' density (`variable_density`)",
    )
    parser.add_argument(
        "--twin",
        action="store_true",
        help="also run the section released at its draft, and subtract its motion",
    )
    parser.add_argument("--out", help="results file name (default: by section)")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    name = "heave_decay" if args.section == "box" else f"heave_decay_{args.section}"
    path = HERE / "results" / (args.out or f"{name}_cpu")
    measure_row = functools.partial(
        measure,
        args.section,
        tank=args.tank,
        depth=args.depth,
        offset=args.offset,
        t_end=args.t_end,
        fit=args.fit,
        scheme=args.scheme,
        variable_density=args.variable_density,
        twin=args.twin,
    )
    write_spacings(path, args, measure_row, markdown)
    rows = json.loads(path.with_suffix(".json").read_text())["rows"]
    plot(rows, path.with_suffix(".png"), args.offset)


if __name__ == "__main__":
    main()
