"""Still-water pressure noise of the `standard` and `high_accuracy` presets at their
default settings, over tanks of several sizes and resolutions.

`hydrostatic` tanks (width x depth: 0.2 x 0.2, 0.5 x 0.3, 1.0 x 0.5 m; 0.3 x
0.15 m; l0 = 1 and 2 cm), adaptive steps (the default), 2 s from rest. At the
bottom probe (`pressure_bottom`, the fluid within 1.5 l0 of the bottom centre):
the mean over 0.5-2 s against rho g (H - y_p) (`scenes.hydrostatic_pressure`),
and the noise: the standard deviation over 0.5-2 s, both relative to that value.
The high-accuracy scheme must be no noisier than `standard` in any tank; the
`standard_ds` column is the standard scheme with the unshifted gradient and
dynamic stabilisation (`schemes.standard(dynamic_stabilisation=True)`).

With `--starts K` each case runs from K starts, the lattice and K - 1 with the
fluid's positions moved by N(0, `--perturbation` x l0), and the table gives the
mean and the spread (std) over the starts, so that a difference between schemes
can be told from the start's chance; the noise is also split into its slow part
(the std of the 0.1 s running mean: sloshing that the start leaves) and its fast
part (what is left: step-to-step jitter).

Run: python validation/still_water_noise.py [--spacings 0.02] [--dt-max 5e-4
[--relaxation-step calm] --out still_water_noise_dt_0.5ms_cpu] [--starts 3
--out still_water_noise_starts_cpu]  (writes results/still_water_noise_cpu.{json,md}
or the --out name)
"""

import argparse
import json
import pathlib
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import machine_info

import jaxmps

HERE = pathlib.Path(__file__).parent
TANKS = ((0.2, 0.2), (0.3, 0.15), (0.5, 0.3), (1.0, 0.5))
SPACINGS = (0.02, 0.01)
SCHEMES = ("standard", "high_accuracy", "standard_ds")


def perturbed(case, seed: int, perturbation: float):
    """The case's state with its fluid moved by N(0, perturbation x l0) (seed 0:
    unmoved)."""
    state = case.state
    if seed == 0:
        return state
    fluid = np.asarray(state.kind) == int(jaxmps.Kind.FLUID)
    rng = np.random.default_rng(seed)
    move = rng.normal(0.0, perturbation * case.config["spacing"], state.position.shape)
    position = state.position + np.where(fluid[:, None], move, 0.0)
    return eqx.tree_at(lambda s: s.position, state, jnp.asarray(position))


def split(p: np.ndarray, window: int = 10) -> tuple[float, float]:
    """(slow, fast): the std of the running mean over `window` samples and of
    what is left, over the samples the running mean covers fully."""
    mean = np.convolve(p, np.ones(window) / window, mode="same")[window:-window]
    return float(mean.std()), float((p[window:-window] - mean).std())


def run(
    width,
    depth,
    spacing,
    scheme,
    t_end=2.0,
    dt_max=None,
    relaxation=None,
    seed=0,
    perturbation=0.01,
):
    case = jaxmps.scenes.hydrostatic(
        width=width,
        depth=depth,
        spacing=spacing,
        scheme=scheme,
        dt_max=dt_max,
        relaxation_step=relaxation,
    )
    probe = {p.name: p for p in case.probes}["pressure_bottom"]
    reference = jaxmps.scenes.hydrostatic_pressure(case)
    start = time.perf_counter()
    out = jaxmps.simulate(
        case.scene,
        case.params,
        perturbed(case, seed, perturbation),
        times=np.arange(0.01, t_end + 1e-9, 0.01),
        observe=jaxmps.scenes.observe_probes((probe,)),
        throw=False,
    )
    wall = time.perf_counter() - start
    t = np.asarray(out.saved["time"])
    p = np.asarray(out.saved["pressure_bottom"])[t >= 0.5]
    slow, fast = split(p)
    return dict(
        width=width,
        depth=depth,
        spacing=spacing,
        scheme=scheme,
        dt_max=float(case.params.dt),
        particles=int(case.state.active.sum()),
        seed=seed,
        mean_error=float(p.mean() / reference - 1),
        noise=float(p.std() / reference),
        slow=slow / reference,
        fast=fast / reference,
        steps=int(np.asarray(out.steps.accepted).sum()),
        result="ok" if out.result == jaxmps.Result.successful else str(out.result),
        wall_s=wall,
    )


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacings", type=float, nargs="+", default=list(SPACINGS))
    p.add_argument(
        "--dt-max",
        type=float,
        default=None,
        help="the adaptive step's upper bound [s] (default: the scene's)",
    )
    p.add_argument(
        "--relaxation-step",
        default=None,
        help="the scenes' relaxation_step ('calm' or seconds; default: per step)",
    )
    p.add_argument("--starts", type=int, default=1, help="starts per case")
    p.add_argument(
        "--perturbation",
        type=float,
        default=0.01,
        help="std of the fluid's displacement at the perturbed starts [l0]",
    )
    p.add_argument("--out", default="still_water_noise_cpu", help="results name")
    args = p.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    rows = []
    for width, depth in TANKS:
        for spacing in args.spacings:
            if width / spacing > 60 and spacing < 0.02:
                continue  # the 1 m tank at 1 cm: 5000 particles, left to a GPU
            for scheme in SCHEMES:
                relax = args.relaxation_step
                relax = relax if relax in (None, "calm") else float(relax)
                for seed in range(args.starts):
                    rows.append(
                        run(
                            width,
                            depth,
                            spacing,
                            scheme,
                            dt_max=args.dt_max,
                            relaxation=relax,
                            seed=seed,
                            perturbation=args.perturbation,
                        )
                    )
                    print(rows[-1], flush=True)
    out = dict(machine=machine_info(), rows=rows, starts=args.starts)
    (HERE / "results" / f"{args.out}.json").write_text(json.dumps(out, indent=1))
    (HERE / "results" / f"{args.out}.md").write_text(markdown(out, args))


def _stats(rows: list[dict], key: str) -> tuple[float, float]:
    values = np.array([r[key] for r in rows])
    return float(values.mean()), float(values.std())


def markdown(out: dict, args) -> str:
    """The table: per tank and scheme the mean error and the noise (mean +- std
    over the starts where there are several), and the noise ratios."""
    groups: dict = {}
    for r in out["rows"]:
        key = (r["width"], r["depth"], r["spacing"])
        groups.setdefault(key, {}).setdefault(r["scheme"], []).append(r)
    several = out["starts"] > 1

    def noise(rows, key="noise"):
        mean, spread = _stats(rows, key)
        return (
            f"{100 * mean:.2f} % +- {100 * spread:.2f}"
            if several
            else f"{100 * mean:.2f} %"
        )

    lines = [
        "# Still-water bottom pressure: standard, high_accuracy and standard_ds "
        "(float64, CPU)",
        "",
        "Default settings (adaptive steps), 2 s from rest, statistics over 0.5-2 s,",
        "relative to rho g (H - y_p). Largest step: "
        + ("the scene's" if args.dt_max is None else f"dt_max = {args.dt_max} s")
        + " (the step taken in still water); the density relaxed "
        + (
            "per step"
            if args.relaxation_step is None
            else f"per relaxation_step={args.relaxation_step!r}"
        )
        + ".",
    ]
    if several:
        lines += [
            f"{out['starts']} starts per case (the lattice and the fluid moved by "
            f"N(0, {args.perturbation} l0)): mean +- std over them. Slow: the "
            "std of the 0.1 s running mean; fast: the rest.",
        ]
    lines += [
        "",
        "| tank W x H [m] | l0 [m] | particles | standard mean / noise "
        "| high_accuracy mean / noise | standard_ds mean / noise "
        "| HA noise / standard | HA noise / standard_ds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (width, depth, spacing), by in groups.items():
        s, h, d = (by[name] for name in SCHEMES)
        lines.append(
            f"| {width} x {depth} | {spacing} | {s[0]['particles']} "
            + "".join(
                f"| {100 * _stats(r, 'mean_error')[0]:+.2f} % / {noise(r)} "
                for r in (s, h, d)
            )
            + f"| {_stats(h, 'noise')[0] / _stats(s, 'noise')[0]:.2f} "
            f"| {_stats(h, 'noise')[0] / _stats(d, 'noise')[0]:.2f} |"
        )
    if several:
        lines += [
            "",
            "| tank W x H [m] | l0 [m] | standard slow / fast "
            "| high_accuracy slow / fast | standard_ds slow / fast |",
            "|---|---|---|---|---|",
        ]
        for (width, depth, spacing), by in groups.items():
            lines.append(
                f"| {width} x {depth} | {spacing} "
                + "".join(
                    f"| {noise(by[name], 'slow')} / {noise(by[name], 'fast')} "
                    for name in SCHEMES
                )
                + "|"
            )
    lines += ["", f"Machine: {out['machine']}"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
