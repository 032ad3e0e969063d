"""Elastic cantilever against Euler-Bernoulli, and the elastic step's stability map.

1. Convergence: `scenes.elastic_cantilever` (0.2 x 0.02 m, E = 1e7 Pa, nu = 0.3,
   rho = 1000 kg/m^3, clamped by three layers) released from rest under gravity
   at 4, 8 and 16 particles through the thickness. Undamped, the tip oscillates
   about its static deflection with the first mode's period: the mean over whole
   periods (between the first and last upward crossings of the run's mean) is the
   static deflection, the crossings' spacing the period. Both against
   Euler-Bernoulli (`scenes.cantilever_theory`; plane strain in 2-D).
   `--seed-model` runs these rows without the surface correction
   (`ElasticBodies.surface_correction=False`), the seed's model.
2. Large deflections (`--large`): the 8-layer beam, softened so that its
   Euler-Bernoulli tip drop under its weight is 10 %, 30 % and 50 % of its length,
   brought to rest by kinetic relaxation (every velocity zeroed whenever the tip's
   speed passes a peak), against the inextensible elastica of a cantilever under
   its own weight (solved here by shooting). The model's own small-deflection
   softness (its drop over Euler-Bernoulli's at the default E, relaxed the same
   way) is divided out, so the row tests the geometric nonlinearity, and the
   chord from the clamp's face to the tip (reach and drop) against the elastica's
   tests that the beam stays bounded and does not stretch.
3. Stability map (`--map 2d 3d moduli`): the 8-layer beam with dt = 1 ms split
   into fewer and fewer sub-steps (`add_elastic_bodies(substeps=...)`, the limit
   checks lifted): whether 150 steps run without a failure and stay bounded, in
   units of h c_s / l0 and h c_p / l0. "2d" and "3d": E = 1e6 Pa, g = 0.981, for
   nu = 0, 0.3, 0.48; "moduli": the 2-D beam at nu = 0.3 under g = 9.81 with
   E = 1e6, 1e7, 1e8 Pa (a map over dt x E at loads from large to small
   deflections).

Run: python validation/elastic_cantilever.py [--layers 4 8 16] [--large]
[--map 2d 3d moduli] [--seed-model]
(writes results/elastic_cantilever_cpu.{json,md}).
"""

import argparse
import dataclasses
import json
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import HERE, machine_info

import jaxmps


def rollout(case, t_end, every=0.002):
    """The tip's vertical displacement every `every` seconds, the wall time [s]
    and the run's result."""
    times = np.arange(1, int(round(t_end / every)) + 1) * every
    observe = jaxmps.scenes.observe_probes(case.probes)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene, case.params, case.state, times=times, observe=observe, throw=False
    )
    wall = time.perf_counter() - start
    axis = "tip_y" if case.scene.dim == 2 else "tip_z"
    return times, np.asarray(out.saved[axis]), wall, out.result


def period_and_mean(times, y):
    """The oscillation's period (mean spacing of upward crossings of the mean, by
    linear interpolation) and its mean over the whole periods between them."""
    level = y.mean()
    up = np.nonzero((y[:-1] < level) & (y[1:] >= level))[0]
    crossing = times[up] + (level - y[up]) / (y[up + 1] - y[up]) * (times[1] - times[0])
    inside = (times >= crossing[0]) & (times < crossing[-1])
    return float(np.diff(crossing).mean()), float(y[inside].mean()), len(crossing)


def convergence_row(layers, periods, corrected=True):
    case = jaxmps.scenes.elastic_cantilever(spacing=0.02 / layers)
    if not corrected:  # the seed's model
        elastic = dataclasses.replace(case.scene.elastic, surface_correction=False)
        case = dataclasses.replace(
            case, scene=dataclasses.replace(case.scene, elastic=elastic)
        )
    theory = jaxmps.scenes.cantilever_theory(case.config)
    times, y, wall, result = rollout(case, periods * theory["period"])
    period, mean, crossings = period_and_mean(times, y)
    return dict(
        layers=layers,
        corrected=corrected,
        spacing=case.config["spacing"],
        particles=int(case.state.active.sum()),
        substeps=case.scene.elastic.substeps,
        dt_max=float(case.params.dt),
        period=period,
        period_theory=theory["period"],
        period_error=period / theory["period"] - 1,
        deflection=-mean,
        deflection_theory=theory["deflection"],
        deflection_error=-mean / theory["deflection"] - 1,
        crossings=crossings,
        wall_s=wall,
        result=str(result),
    )


def elastica(load: float, points: int = 2000) -> tuple[float, float]:
    """The inextensible elastica of a cantilever under its own weight: its tip's
    drop and reach over L for load = q L^3 / (E' I) (Euler-Bernoulli's drop is
    load / 8). With s the arc length over L and theta the slope,
    theta'' = -load (1 - s) cos(theta), theta(0) = 0, theta'(1) = 0; shooting on
    theta'(0) in [0, load / 2] (bisection), classical Runge-Kutta in s."""
    h = 1.0 / points

    def shoot(k):
        def rhs(s, y):
            return np.array([y[1], -load * (1 - s) * np.cos(y[0])])

        y, s, drop, reach = np.array([0.0, k]), 0.0, 0.0, 0.0
        for _ in range(points):
            k1 = rhs(s, y)
            k2 = rhs(s + h / 2, y + h / 2 * k1)
            k3 = rhs(s + h / 2, y + h / 2 * k2)
            k4 = rhs(s + h, y + h * k3)
            new = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            # Simpson on the interval's ends and midpoint slope
            mid = 0.5 * (y[0] + new[0]) + h / 8 * (y[1] - new[1])
            drop += h / 6 * (np.sin(y[0]) + 4 * np.sin(mid) + np.sin(new[0]))
            reach += h / 6 * (np.cos(y[0]) + 4 * np.cos(mid) + np.cos(new[0]))
            y, s = new, s + h
        return y[1], drop, reach

    low, high = 0.0, 0.5 * load
    for _ in range(60):
        k = 0.5 * (low + high)
        if shoot(k)[0] > 0:
            high = k
        else:
            low = k
    _, drop, reach = shoot(0.5 * (low + high))
    return drop, reach


def relaxed(case, max_periods=12.0, chunks_per_period=40):
    """The tip's static (x, y) displacement by kinetic relaxation: the run goes
    on in chunks of a 40th of the Euler-Bernoulli period, and whenever the tip's
    speed over a chunk falls below the last chunk's (a kinetic-energy peak passed)
    every velocity and spin is zeroed. Stops when the tip moves by less than
    1e-5 L over a period, or after `max_periods`."""
    theory = jaxmps.scenes.cantilever_theory(case.config)
    length = case.config["length"]
    chunk = theory["period"] / chunks_per_period
    probes = {p.name: p for p in case.probes}

    def tip(state):
        return np.array(
            [float(probes[n](case.scene, state)) for n in ("tip_x", "tip_y")]
        )

    def rest(state):
        e = state.elastic
        velocity = state.velocity.at[e.index].set(0.0)
        elastic = eqx.tree_at(
            lambda e: (e.velocity, e.angular_velocity),
            e,
            (jnp.zeros_like(e.velocity), jnp.zeros_like(e.angular_velocity)),
        )
        return eqx.tree_at(
            lambda s: (s.velocity, s.elastic), state, (velocity, elastic)
        )

    state, start = case.state, time.perf_counter()
    history, speed, resets = [tip(state)], 0.0, 0
    for i in range(int(max_periods * chunks_per_period)):
        out = jaxmps.simulate(
            case.scene,
            case.params,
            state,
            times=[float(state.time) + chunk],
            throw=False,
        )
        if out.result != jaxmps.Result.successful:
            return dict(result=str(out.result), tip=history[-1], resets=resets)
        state = out.state
        history.append(tip(state))
        new_speed = np.linalg.norm(history[-1] - history[-2]) / chunk
        if new_speed < speed:
            state, resets, new_speed = rest(state), resets + 1, 0.0
        speed = new_speed
        if i >= chunks_per_period:
            moved = np.linalg.norm(history[-1] - history[-1 - chunks_per_period])
            if moved < 1e-5 * length:
                break
    return dict(
        result="successful",
        tip=history[-1],
        resets=resets,
        periods=len(history) / chunks_per_period,
        wall_s=time.perf_counter() - start,
    )


def large_rows(drops=(0.1, 0.3, 0.5), layers=8):
    """The beam at the default E (its small-deflection softness) and softened to
    each Euler-Bernoulli drop / L in `drops`, relaxed to rest, against the
    elastica."""
    base = dict(spacing=0.02 / layers)
    c = jaxmps.scenes.elastic_cantilever(**base).config
    length, t, nu = c["length"], c["thickness"], c["poisson_ratio"]
    q = c["solid_density"] * c["gravity"] * t
    inertia = t**3 / 12

    def modulus(load):
        return (1 - nu**2) * q * length**3 / (load * inertia)

    rows, softness = [], None
    loads = [q * length**3 / (c["youngs_modulus"] / (1 - nu**2) * inertia)]
    loads += [8 * d for d in drops]
    for load in loads:
        case = jaxmps.scenes.elastic_cantilever(**base, youngs_modulus=modulus(load))
        got = relaxed(case)
        drop, reach = elastica(load)
        tip_x, tip_y = got["tip"]
        model_drop = -tip_y / length
        if softness is None:
            softness = model_drop / drop
        rows.append(
            dict(
                load=load,
                youngs_modulus=modulus(load),
                euler_bernoulli=load / 8,
                elastica_drop=drop,
                elastica_reach=reach,
                drop=model_drop,
                reach=1 + tip_x / length,
                softness=model_drop / drop,
                drop_over_softness=model_drop / softness,
                error=model_drop / softness / drop - 1,
                chord=float(np.hypot(1 + tip_x / length, tip_y / length)),
                elastica_chord=float(np.hypot(reach, drop)),
                **{k: v for k, v in got.items() if k != "tip"},
            )
        )
        print(json.dumps(rows[-1]), flush=True)
    return rows


def stability_row(
    nu, substeps, youngs_modulus=1e6, gravity=0.981, dim=2, steps=150, dt=1e-3
):
    """The 8-layer beam (`dim` 2 or 3) at `youngs_modulus`, `gravity`, run for
    `steps` steps of `dt`, each in `substeps` sub-steps, the limit checks lifted.
    Stable: the run ends successful, finite, and the tip stays within the larger
    of 10 % of the length and 2.5 Euler-Bernoulli static deflections (an undamped
    release from rest swings to twice that at most)."""
    overrides = dict(
        youngs_modulus=youngs_modulus,
        poisson_ratio=nu,
        gravity=gravity,
        spacing=0.0025,
        dt=dt,
        dim=dim,
    )
    case = jaxmps.scenes.elastic_cantilever(**overrides)
    model = case.scene.elastic
    lifted = jaxmps.bodies.ElasticBodies(
        count=model.count,
        spacing=model.spacing,
        substeps=substeps,
        courant=100.0,
        pressure_courant=100.0,
    )
    case = dataclasses.replace(
        case, scene=dataclasses.replace(case.scene, elastic=lifted)
    )
    start = time.perf_counter()
    times, y, _, result = rollout(case, steps * dt, every=steps * dt / 30)
    wall = time.perf_counter() - start
    config = jaxmps.scenes.available()["elastic_cantilever"] | overrides
    static = jaxmps.scenes.cantilever_theory(config)["deflection"]
    bound = max(0.1 * config["length"], 2.5 * static)
    lam, mu = (float(v) for v in jaxmps.bodies.lame(youngs_modulus, nu))
    h = dt / substeps
    stable = bool(
        result == jaxmps.Result.successful
        and np.all(np.isfinite(y))
        and np.abs(y).max() < bound
    )
    return dict(
        dim=dim,
        youngs_modulus=youngs_modulus,
        gravity=gravity,
        dt=dt,
        steps=steps,
        poisson_ratio=nu,
        substeps=substeps,
        particles=int(case.state.elastic.index.shape[0]),
        h_cs_l0=h * np.sqrt(mu / 1000.0) / 0.0025,
        h_cp_l0=h * np.sqrt((lam + 2 * mu) / 1000.0) / 0.0025,
        static_theory=static,
        largest_tip=float(np.nanmax(np.abs(y))) if np.any(np.isfinite(y)) else None,
        stable=stable,
        result=str(result),
        wall_s=wall,
    )


def substeps_for(target, youngs_modulus, nu, dt=1e-3, spacing=0.0025):
    """The sub-step count whose h c_s / l0 is nearest `target`."""
    _, mu = (float(v) for v in jaxmps.bodies.lame(youngs_modulus, nu))
    return max(1, round(dt * np.sqrt(mu / 1000.0) / (spacing * target)))


def _map_key(r, last="substeps"):
    """A map row's case (dim, g, E, nu) and its `last` field: "substeps" names
    the row (a re-run replaces it), "h_cs_l0" orders the table."""
    return (
        r.get("dim", 2),
        r.get("gravity", 0.981),
        r.get("youngs_modulus", 1e6),
        r["poisson_ratio"],
        r[last],
    )


def map_cases(which):
    """(dim, E, g, nu, substeps) of a map: "2d" the beam at E = 1e6 Pa, g = 0.981
    over three nu; "3d" the same in 3-D; "moduli" the 2-D beam at nu = 0.3 and
    g = 9.81 over E = 1e6, 1e7, 1e8 Pa; each at sub-steps bracketing the onset."""
    targets = (0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5)
    if which == "moduli":
        return [
            (2, e, 9.81, 0.3, substeps_for(t, e, 0.3))
            for e in (1e6, 1e7, 1e8)
            for t in targets
        ]
    dim = 3 if which == "3d" else 2
    return [
        (dim, 1e6, 0.981, nu, substeps_for(t, 1e6, nu))
        for nu in (0.0, 0.3, 0.48)
        for t in targets
    ]


def markdown(rows, stability, info, large=()):
    lines = [
        "# Elastic cantilever against Euler-Bernoulli",
        "",
        f"Machine: {info.get('cpu_model', '?')}; float64; "
        "`validation/elastic_cantilever.py`.",
        "0.2 x 0.02 m beam, E = 1e7 Pa, nu = 0.3, rho = 1000 kg/m^3, g = 9.81, "
        "released from rest; theory: plane strain, E' = E / (1 - nu^2).",
        "",
        "Model: 'corrected' is the default (`ElasticBodies.surface_correction`),",
        "'seed' the seed's model without it.",
        "",
        "| model | layers | l0 [mm] | particles | substeps | period [s] | theory [s] |"
        " error | static tip [mm] | theory [mm] | error | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        model = "corrected" if r.get("corrected", True) else "seed"
        lines.append(
            f"| {model} | {r['layers']} | {1e3 * r['spacing']:.3g} | {r['particles']} |"
            f" {r['substeps']} | {r['period']:.4f} | {r['period_theory']:.4f} |"
            f" {100 * r['period_error']:+.1f} % | {1e3 * r['deflection']:.3f} |"
            f" {1e3 * r['deflection_theory']:.3f} |"
            f" {100 * r['deflection_error']:+.1f} % | {r['wall_s']:.0f} |"
        )
    if large:
        lines += [
            "",
            "## Large deflections (8 layers, relaxed to rest, against the elastica)",
            "",
            "load = q L^3 / (E' I); 'softness' is the model's drop over the",
            "elastica's; 'drop / softness' divides out the first row's (the default",
            "E), leaving the geometric nonlinearity; chord = |clamp face to tip| / L.",
            "",
            "| load | E [Pa] | Euler-Bernoulli drop / L | elastica drop / L |"
            " model drop / L | softness | drop / softness | error | model reach / L |"
            " elastica reach / L | model chord | elastica chord | resets | periods |"
            " result |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in large:
            lines.append(
                f"| {r['load']:.3f} | {r['youngs_modulus']:.3g} |"
                f" {r['euler_bernoulli']:.4f} | {r['elastica_drop']:.4f} |"
                f" {r['drop']:.4f} | {r['softness']:.3f} |"
                f" {r['drop_over_softness']:.4f} | {100 * r['error']:+.1f} % |"
                f" {r['reach']:.4f} | {r['elastica_reach']:.4f} | {r['chord']:.4f} |"
                f" {r['elastica_chord']:.4f} | {r['resets']} |"
                f" {r.get('periods', float('nan')):.1f} | {r['result']} |"
            )
    if stability:
        lines += [
            "",
            "## Stability map (8 layers, dt = 1 ms in sub-steps h, 150 steps)",
            "",
            "Stable: the run ends successful and finite with the tip within the",
            "larger of 0.1 L and 2.5 Euler-Bernoulli static deflections. The",
            "2-D rows at g = 0.981 have the load of E = 1e7 Pa under 9.81 at",
            "E = 1e6 Pa; the rows at g = 9.81 move E at a fixed step (a map over",
            "dt x E: the static deflection is 5.4 mm at 1e7 Pa, 0.54 at 1e8, 54 at",
            "1e6). 3-D: the square section, 5,312 particles.",
            "",
            "| dim | E [Pa] | g [m/s^2] | nu | substeps | h c_s / l0 | h c_p / l0 |"
            " largest tip [mm] | EB static [mm] | stable | wall [s] | host |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in sorted(stability, key=lambda r: _map_key(r, "h_cs_l0")):
            tip = r.get("largest_tip")
            static = r.get("static_theory")
            wall = r.get("wall_s")
            lines.append(
                f"| {r.get('dim', 2)} | {r.get('youngs_modulus', 1e6):.0e} |"
                f" {r.get('gravity', 0.981)} | {r['poisson_ratio']} |"
                f" {r['substeps']} | {r['h_cs_l0']:.3f} | {r['h_cp_l0']:.3f} |"
                f" {'-' if tip is None else f'{1e3 * tip:.2f}'} |"
                f" {'-' if static is None else f'{1e3 * static:.2f}'} |"
                f" {'yes' if r['stable'] else 'no'} |"
                f" {'-' if wall is None else f'{wall:.0f}'} |"
                f" {r.get('host', 'as above')} |"
            )
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layers", nargs="*", type=int, default=[4, 8, 16])
    parser.add_argument("--periods", type=float, default=3.2)
    parser.add_argument(
        "--map",
        nargs="*",
        choices=("2d", "3d", "moduli"),
        default=None,
        help="run the stability map (rows of the same case replaced)",
    )
    parser.add_argument(
        "--large", action="store_true", help="run the large-deflection rows"
    )
    parser.add_argument(
        "--seed-model",
        action="store_true",
        help="the convergence rows without the surface correction",
    )
    parser.add_argument("--out", default="elastic_cantilever_cpu")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    path = HERE / "results" / args.out
    rows, stability, large = [], [], []
    if path.with_suffix(".json").exists():
        old = json.loads(path.with_suffix(".json").read_text())
        corrected = not args.seed_model
        rows = [
            r
            for r in old["rows"]
            if r["layers"] not in args.layers or r.get("corrected", True) != corrected
        ]
        stability = old.get("stability", [])
        large = [] if args.large else old.get("large", [])
    here = machine_info()
    # the file's machine is that of its convergence and large-deflection rows;
    # each map row names its own host
    info = (
        here
        if args.layers or args.large or not path.with_suffix(".json").exists()
        else old["machine"]
    )

    def write():
        rows.sort(key=lambda r: (not r.get("corrected", True), r["layers"]))
        data = {"machine": info, "rows": rows, "stability": stability, "large": large}
        path.with_suffix(".json").write_text(json.dumps(data, indent=1))
        path.with_suffix(".md").write_text(markdown(rows, stability, info, large))

    for layers in args.layers:
        rows.append(convergence_row(layers, args.periods, not args.seed_model))
        print(json.dumps(rows[-1]), flush=True)
        write()
    if args.large:
        large.extend(large_rows())
        write()
    for which in args.map or ():
        for dim, e, g, nu, substeps in map_cases(which):
            row = stability_row(nu, substeps, e, g, dim)
            row["host"] = here.get("cpu_model", "?")
            stability[:] = [r for r in stability if _map_key(r) != _map_key(row)]
            stability.append(row)
            print(json.dumps(row), flush=True)
            write()


if __name__ == "__main__":
    main()
