"""Seed 002's fixed-bed washout (Ch. 5, V4) and its failure limit on the
(q, Delta H) plane (§8.2 Method A, V7), with `jaxmps.scenes.block_washout`.

A groundsill (crest 6.5 cm, a 2 cm drop, apron 30 cm), 16 rows of blocks below it
on a fixed bed, the scour hole that the bed lowering Delta H implies
(`jaxmps.scenes.scour_hole`: Case 3-2's hole at Delta H = 2 cm, Case 3-3's at
4 cm, linear between), a transition of 0.5 m falling by Delta H, a free overfall
at 2 m; explicit E-MPS (c = 10 m/s, wall pressure from the facing fluid), mu =
0.6. The blocks are held while the flow spins up (`--release` s; the seed: 60 s)
and are then free for `--main` s (the seed classifies at 10 s into its main run:
the washout of the last row, row 1 counted from downstream, is failure).

Seed (2.5 mm): V4: Case 3-2 (Delta H = 2 cm) no block moves; Case 3-3 (4 cm) the
last row washes out, then a cascade (experiment: rows 1-4 within 8 s). V7: for
q = 0.006 / 0.009 / 0.012 m^2/s, Delta H = 2 cm stable, 3 and 4 cm fail.

With `--movable`, seed 002's moving-bed runs (§8.3 Method B, its Tables
8.3-8.4, at its l0 = 5 mm): no hole cut; the blocks (2.0 x 1.5 cm, no gaps,
mass-matched) rest on a bed of DEM grains 7 cm deep that runs from the apron's
end 10 cm past the blocks and on into the transition (`--movable-length`); the
grains of the seed's similarity scaling, R = 1.65 x 0.76 mm / d (0.25 at 5
mm), with its stiffness rule at its Delta t = 5e-5 s (k_n = 323 N/m at 5 mm);
grains and blocks feel no flow until the release. The seed's Fig. 8.6 at 60 s:
Delta H = 4 cm fails for every q (more blocks out as q grows), 0 and 2 cm do
not; where the sediment lay in its figure 8.5 is lost from the text, so the
bed's extent here is ours.

Each Delta H is one vmapped batch over the discharges (`jaxmps.sweep` over
`inflow.velocity` and `inflow.depth`, on the case built for the largest q, whose
initial water and inflow boundary the others share; the spin-up evens that out).

Run: PYTHONPATH=. python validation/block_washout.py [--spacing 0.0025]
[--release 4] [--main 10] [--lowerings 0.02 0.04] [--discharges 0.006] [--merge]
(writes results/block_washout_<tag>_cpu.{json,md,png}; with --merge the rows of
that file run with the same settings are kept and only the missing (Delta H, q)
cells are run, each on the case built for the largest q asked for, as in one
batch).
"""

import argparse
import json
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import HERE, machine_info

import jaxmps

jax.config.update("jax_enable_x64", True)

SEED = {0.02: "stable", 0.03: "fail", 0.04: "fail"}  # §8.2, every q
# §8.3 (Fig. 8.6, 60 s), every q
SEED_MOVABLE = {0.0: "stable", 0.02: "stable", 0.04: "fail"}


def blocks(spacing: float) -> dict:
    """The seed's blocks at its l0: 1.75 x 1.25 cm 2.5 mm apart at 2.5 mm (Ch. 5,
    §8.2); 2.0 x 1.5 cm without gaps at 5 mm (§8.3)."""
    if spacing <= 0.0025 + 1e-12:
        return {}
    return dict(block_length=0.02, block_height=0.015, block_gap=0.0)


SEED_STEP = 5e-5  # s, seed 002's Delta t for its moving-bed runs (Table 8.3)


def movable_bed(args) -> dict:
    """The moving-bed settings (`--movable`): no hole, the blocks on grains of
    the seed's scaling (R = 1.65 x 0.76 mm / d) and stiffness (its rule at its
    Delta t, `bodies.rule_stiffness` of a grain's submerged mass)."""
    if not args.movable:
        return {}
    rows, size = 16, blocks(args.spacing)
    extent = rows * (size.get("block_length", 0.0175) + size.get("block_gap", 0.0025))
    relative = 1.65 * 0.00076 / args.spacing
    mass = 1000.0 * relative * jaxmps.bodies.sphere_volume(args.spacing)
    return dict(
        scour_length=0.0,
        scour_depth=0.0,
        scour_exposure=0.0,
        reach_length=extent + 0.1,
        movable_length=extent + 0.1 + args.movable_length,
        movable_depth=0.07,
        grain_density=1000.0 * (1.0 + relative),
        stiffness=float(jaxmps.bodies.rule_stiffness(mass, SEED_STEP)),
        rolling=getattr(args, "rolling", 0.0),
    )


def displacements(case, saved) -> np.ndarray:
    """Each block's distance from its start [m], (saves, rows) or (b, saves,
    rows)."""
    rows = int(case.config["block_rows"])
    start = np.asarray(case.state.rigid.centre)
    x = np.stack([np.asarray(saved[f"block{k}_x"]) for k in range(rows)], -1)
    y = np.stack([np.asarray(saved[f"block{k}_y"]) for k in range(rows)], -1)
    return np.hypot(x - start[:, 0], y - start[:, 1])


def departures(t, moved, length) -> list:
    """When each row left its place (moved by more than `length`) [s], rows
    counted from downstream (row 1 is the last one); None for rows that stayed."""
    out = []
    for k in range(moved.shape[-1] - 1, -1, -1):
        gone = np.nonzero(moved[:, k] > length)[0]
        out.append(None if not len(gone) else round(float(t[gone[0]]), 3))
    return out


class _Runs:
    """One `simulate` per member, gathered like a `SweepResult`."""

    def __init__(self, runs):
        self.saved = {
            k: np.stack([np.asarray(r.saved[k]) for r in runs]) for k in runs[0].saved
        }
        self._messages = [jaxmps._result.result_name(r.result) for r in runs]

    def messages(self):
        return self._messages


def serial(case, values, times):
    """The members one after another: on a CPU faster than a batch (a batch
    searches for neighbours whenever any member's inflow or outflow switches a
    particle on or off; a run alone carries its lists between those steps)."""
    runs = []
    for m in range(len(next(iter(values.values())))):
        params = case.params
        for name, v in values.items():
            params = eqx.tree_at(
                lambda p, n=name: getattr(p.inflow, n.split(".")[1]),
                params,
                jnp.asarray(v[m], case.params.dt.dtype),
            )
        runs.append(
            jaxmps.simulate(
                case.scene,
                params,
                case.state,
                times=times,
                observe=jaxmps.scenes.observe_probes(case.probes),
                throw=False,
            )
        )
    return _Runs(runs)


def run_lowering(args, lowering: float, done=()) -> list[dict]:
    """One Delta H: a batch over the discharges (one run when only one). The
    case is built for the largest discharge asked for, so a member run alone
    (the others in `done`, rows of an earlier run) starts as it would in the
    batch."""
    q_max = max(args.discharges)
    kept = [r for r in done if r["bed_lowering"] == lowering]
    discharges = [q for q in args.discharges if all(r["discharge"] != q for r in kept)]
    if not discharges:
        return kept
    case = jaxmps.scenes.block_washout(
        spacing=args.spacing,
        discharge=q_max,
        bed_lowering=lowering,
        release_time=args.release,
        t_end=args.release + args.main,
        **blocks(args.spacing),
        **movable_bed(args),
    )
    times = np.round(
        np.arange(1, round((args.release + args.main) / args.every) + 1) * args.every, 9
    )
    feeds = [jaxmps.scenes.critical_feed(case, q) for q in discharges]
    start = time.perf_counter()
    values = {
        "inflow.velocity": np.array([u for u, _ in feeds]),
        "inflow.depth": np.array([h for _, h in feeds]),
    }
    out = (serial if args.serial else jaxmps.sweep)(case, values, times=times)
    wall = time.perf_counter() - start
    length = float(case.config["block_length"])
    moved = displacements(case, out.saved)
    rows = []
    for m, q in enumerate(discharges):
        after = times - args.release
        gone = np.asarray(out.saved["blocks_out"])[m]
        at_classify = gone[np.argmin(np.abs(after - min(args.classify, args.main)))]
        rows.append(
            dict(
                discharge=q,
                bed_lowering=lowering,
                hole=[round(v, 4) for v in case.config["hole"]],
                exposure=case.config["scour_exposure"],
                inflow=[round(v, 5) for v in feeds[m]],
                result=out.messages()[m],
                blocks_out_at_classify=int(round(float(at_classify))),
                blocks_out_end=int(round(float(gone[-1]))),
                verdict="fail" if at_classify > 0.5 else "stable",
                seed=(SEED_MOVABLE if args.movable else SEED).get(round(lowering, 3)),
                departures=departures(after, moved[m], length),
                largest_move_mm=round(1e3 * float(moved[m].max()), 3),
                last_row_move_mm=[round(1e3 * float(v), 3) for v in moved[m][:, -1]],
                times=[round(float(v), 3) for v in after],
                blocks_out=[int(round(float(v))) for v in gone],
                fluid_count=[int(v) for v in np.asarray(out.saved["fluid_count"])[m]],
            )
        )
    particles = int(np.asarray(case.state.active).sum())
    steps = (args.release + args.main) / float(case.params.dt)
    for row in rows:
        row.update(
            wall_s=round(wall, 1),
            members=len(discharges),
            batch="serial" if args.serial else "sweep",
            particles=particles,
            slots=int(case.scene.capacity),
            steps=int(steps),
        )
    print(
        f"Delta H = {lowering:g}: {[r['verdict'] for r in rows]} "
        f"(out {[r['blocks_out_end'] for r in rows]}), {wall:.0f} s",
        flush=True,
    )
    return sorted(kept + rows, key=lambda r: r["discharge"])


SAME_RUN = ("spacing", "release", "main", "classify", "every", "movable", "rolling")


def earlier_rows(args, stem) -> list[dict]:
    """With --merge, the rows of the results file already there whose run had
    the same settings: those (Delta H, q) are not run again."""
    path = stem.with_suffix(".json")
    if not (args.merge and path.exists()):
        return []
    earlier = json.loads(path.read_text())
    same = all(earlier["args"].get(k, 0.0) == getattr(args, k, 0.0) for k in SAME_RUN)
    return earlier["rows"] if same else []


def _bed_line(args) -> list[str]:
    """The movable bed's settings, as a paragraph (none for the fixed bed)."""
    if not args.movable:
        return []
    bed = movable_bed(args)
    return [
        f"Grains d = l0, {bed['grain_density']:.1f} kg/m^3, k_n "
        f"{bed['stiffness']:.0f} N/m (seed 002's rule at its dt {SEED_STEP:g} s), "
        f"mu_r {bed['rolling']:g}; the bed {bed['movable_length']:.2f} m long from "
        f"the apron's end, at least {100 * bed['movable_depth']:g} cm deep (laid "
        "deeper by whole spacings until a row of grains ends flush under the "
        "blocks); no hole cut.",
        "",
    ]


def markdown(args, rows, info) -> str:
    lines = [
        (
            "# Washout on a movable bed (seed 002 §8.3, Method B)"
            if args.movable
            else "# Fixed-bed washout (seed 002 Ch. 5, §8.2)"
        )
        + f": l0 = {args.spacing * 1e3:g} mm",
        "",
        f"Spin-up {args.release:g} s with the blocks held, then {args.main:g} s free; "
        f"classified {min(args.classify, args.main):g} s after the release (fail: a "
        "block has left its place by more than its length). "
        f"Host: {info.get('cpu_model') or '?'}, float64.",
        "",
        *_bed_line(args),
        "| q [m^2/s] | Delta H [cm] | hole L / Z_d / Z_b [cm] | verdict (seed) | "
        "rows out at classify / end | rows' departures [s after release], row 1 "
        "= last | largest move [mm] | wall [s] (members) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        hole = " / ".join(f"{100 * v:.2f}" for v in r["hole"][:2]) + (
            f" / {100 * r['exposure']:.2f}"
        )
        if args.movable:
            hole = "none cut (movable bed)"
        left = [d for d in r["departures"] if d is not None]
        lines.append(
            f"| {r['discharge']:g} | {100 * r['bed_lowering']:g} | {hole} | "
            f"{r['verdict']} ({r['seed']}) | {r['blocks_out_at_classify']} / "
            f"{r['blocks_out_end']} | {left or '-'} | {r['largest_move_mm']:.2f} | "
            f"{r['wall_s']:.0f} ({r['members']}) |"
        )
    return "\n".join(lines) + "\n"


def plot(rows, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    for r in rows:
        label = f"q {r['discharge']:g}, dH {100 * r['bed_lowering']:g} cm"
        ax.step(r["times"], r["blocks_out"], where="post", label=label)
        bx.plot(r["times"], r["last_row_move_mm"], label=label)
    ax.set_xlabel("time after release [s]")
    ax.set_ylabel("rows washed out")
    bx.set_xlabel("time after release [s]")
    bx.set_ylabel("last row's displacement [mm]")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacing", type=float, default=0.0025)
    parser.add_argument("--release", type=float, default=4.0)
    parser.add_argument("--main", type=float, default=10.0)
    parser.add_argument("--classify", type=float, default=10.0)
    parser.add_argument("--every", type=float, default=0.1)
    parser.add_argument("--lowerings", type=float, nargs="+", default=[0.02, 0.04])
    parser.add_argument("--discharges", type=float, nargs="+", default=[0.006])
    parser.add_argument(
        "--movable", action="store_true", help="blocks on DEM grains (Method B)"
    )
    parser.add_argument(
        "--movable-length",
        type=float,
        default=0.2,
        help="the grains' reach past the blocks' 10 cm of flat bed [m]",
    )
    parser.add_argument(
        "--rolling",
        type=float,
        default=0.0,
        help="the grains' rolling resistance mu_r with --movable (the seed: 0)",
    )
    parser.add_argument("--tag", default=None)
    parser.add_argument(
        "--serial", action="store_true", help="one run per discharge (faster on CPU)"
    )
    parser.add_argument(
        "--replot", action="store_true", help="redraw the saved results' plot"
    )
    parser.add_argument(
        "--merge",
        action="store_true",
        help="keep the results file's rows of the same settings; run the rest",
    )
    args = parser.parse_args()
    tag = args.tag or f"{args.spacing * 1e3:g}mm".replace(".", "p")
    tag += "_movable" * args.movable
    tag += f"_rolling{args.rolling:g}".replace(".", "p") * (args.rolling > 0)
    stem = HERE / "results" / f"block_washout_{tag}_cpu"
    if args.replot:
        plot(
            json.loads(stem.with_suffix(".json").read_text())["rows"],
            stem.with_suffix(".png"),
        )
        return
    info = machine_info()
    done = earlier_rows(args, stem)
    rows = [
        row for lowering in args.lowerings for row in run_lowering(args, lowering, done)
    ]
    stem.with_suffix(".json").write_text(
        json.dumps(dict(args=vars(args), machine=info, rows=rows), indent=1)
    )
    stem.with_suffix(".md").write_text(markdown(args, rows, info))
    plot(rows, stem.with_suffix(".png"))
    print(markdown(args, rows, info))


if __name__ == "__main__":
    main()
