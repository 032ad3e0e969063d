"""Calibration: the grains' rolling resistance fitted to the published 2-D
runout law of granular column collapse.

Our grains are spheres; with seed 002's free rolling (mu_r = 0) a column of
aspect ratio 5 runs out 27 % beyond the law of Lube et al. (2005) and its
deposit lies at 8 degrees (validation/granular_collapse.py), where angular
sand resists rolling. The fit: for aspect ratios a = 0.5, 1, 3, 5 (outside the
law's transition 1.8-2.8) and three packings each, one vmapped sweep per
column over mu_r; the loss is the mean over a of (ln(runout / law))^2 of the
packings' mean runout; mu_r* the minimum of a parabola through the lowest
three. A derivative-free fit: the runout of a whole collapse is one draw of a
chaotic flow, whose exact gradient is of no use
(calibration/grain_restitution_synthetic.py).

The law (calibration/lube2005_runout_law.csv, with its source):
(L_inf - L0) / L0 = 1.2 a for a < 1.8, 1.9 a^(2/3) for a > 2.8.

Run: python calibration/grain_rolling_runout.py
(writes results/grain_rolling_runout.{json,md,png})
"""

import csv
import json
import math
import pathlib
import time

import jax.numpy as jnp
import numpy as np

import jaxmps

HERE = pathlib.Path(__file__).parent
ASPECTS = (0.5, 1.0, 3.0, 5.0)
ROLLING = (0.0, 0.05, 0.1, 0.15, 0.2)
SEEDS = (0, 1, 2)
WIDTH, SPACING, T_END = 0.05, 0.005, 1.5


def law() -> list[dict]:
    """The runout law's pieces from the CSV (its comment lines are the
    source)."""
    rows = (HERE / "lube2005_runout_law.csv").read_text().splitlines()
    data = [line for line in rows if line and not line.startswith("#")]
    return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(data)]


def law_runout(a: float, pieces: list[dict]) -> float:
    for piece in pieces:
        if piece["a_min"] <= a < piece["a_max"]:
            return piece["coefficient"] * a ** piece["exponent"]
    raise ValueError(f"a = {a} lies in the law's transition.")


def runouts(aspect: float, seed: int) -> tuple[np.ndarray, list[str], float]:
    """The final normalised runout of the column for every `ROLLING` value,
    one vmapped sweep."""
    case = jaxmps.scenes.granular_collapse(
        column_width=WIDTH,
        column_height=aspect * WIDTH,
        spacing=SPACING,
        friction=0.5,
        floor_length=max(0.3, WIDTH * (2.5 + 3 * aspect)),
        seed=seed,
    )
    start = time.perf_counter()
    res = jaxmps.sweep(
        case, {"grains.rolling": jnp.asarray(ROLLING)}, times=[T_END - 0.1, T_END]
    )
    wall = time.perf_counter() - start
    final = np.asarray(res.saved["runout"])[:, -1]
    moved = np.abs(final - np.asarray(res.saved["runout"])[:, 0])
    if np.any(moved > SPACING):
        print(f"a={aspect} seed={seed}: not at rest by {T_END} s: {moved}")
    return (final - WIDTH) / WIDTH, res.messages(), wall


def main():
    pieces = law()
    table = {}
    for a in ASPECTS:
        draws = []
        for seed in SEEDS:
            values, messages, wall = runouts(a, seed)
            bad = [m for m in messages if m != "successful"]
            if bad:
                raise RuntimeError(f"a={a} seed={seed}: {bad[0]}")
            draws.append(values)
            print(
                f"a={a} seed={seed}: {np.round(values, 2)} ({wall:.0f} s)", flush=True
            )
        table[a] = np.asarray(draws)
    mean = {a: table[a].mean(axis=0) for a in ASPECTS}
    loss = np.asarray(
        [
            np.mean(
                [math.log(mean[a][k] / law_runout(a, pieces)) ** 2 for a in ASPECTS]
            )
            for k in range(len(ROLLING))
        ]
    )
    best = int(np.argmin(loss))
    lo = min(max(best - 1, 0), len(ROLLING) - 3)
    x, y = np.asarray(ROLLING[lo : lo + 3]), loss[lo : lo + 3]
    c2, c1, _ = np.polyfit(x, y, 2)
    fitted = float(-c1 / (2 * c2)) if c2 > 0 else float(ROLLING[best])
    fitted = float(np.clip(fitted, ROLLING[0], ROLLING[-1]))
    out = dict(
        aspects=ASPECTS,
        rolling=ROLLING,
        seeds=SEEDS,
        law=pieces,
        runout=table_to_lists(table),
        loss=loss.tolist(),
        fitted_rolling=fitted,
        loss_at_zero=float(loss[0]),
        loss_at_best_grid=float(loss[best]),
    )
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "grain_rolling_runout.json").write_text(
        json.dumps(out, indent=1)
    )
    lines = [
        "# Rolling resistance fitted to the 2-D runout law (Lube et al. 2005)",
        "",
        "Mean normalised runout (L - L0) / L0 over packings "
        f"{list(SEEDS)}, mu = 0.5, L0 = 5 cm, d = 4-5 mm; law in brackets.",
        "",
        "| mu_r | "
        + " | ".join(f"a = {a:g} [{law_runout(a, pieces):.2f}]" for a in ASPECTS)
        + " | loss |",
        "|---|" + "---|" * (len(ASPECTS) + 1),
    ]
    for k, r in enumerate(ROLLING):
        cells = " | ".join(
            f"{mean[a][k]:.2f} +- {table[a][:, k].std():.2f}" for a in ASPECTS
        )
        lines.append(f"| {r:g} | {cells} | {loss[k]:.4f} |")
    lines += ["", f"Fitted mu_r = {fitted:.3f} (parabola through the lowest three)."]
    (HERE / "results" / "grain_rolling_runout.md").write_text("\n".join(lines) + "\n")
    _plot(mean, table, pieces, fitted)
    print("\n".join(lines))


def table_to_lists(table):
    return {str(a): v.tolist() for a, v in table.items()}


def _plot(mean, table, pieces, fitted):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 4))
    a = np.linspace(0.3, 7, 200)
    low, high = a[a < 1.8], a[a > 2.8]
    ax.plot(low, [law_runout(v, pieces) for v in low], "k-", label="Lube et al. 2005")
    ax.plot(high, [law_runout(v, pieces) for v in high], "k-")
    for k, r in enumerate(ROLLING):
        ax.errorbar(
            ASPECTS,
            [mean[v][k] for v in ASPECTS],
            yerr=[table[v][:, k].std() for v in ASPECTS],
            fmt="o-",
            ms=3,
            label=f"mu_r = {r:g}",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(ASPECTS, [f"{t:g}" for t in ASPECTS])
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("a = H0 / L0")
    ax.set_ylabel("(L_inf - L0) / L0")
    ax.set_title(f"fitted mu_r = {fitted:.3f}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(HERE / "results" / "grain_rolling_runout.png", dpi=120)


if __name__ == "__main__":
    main()
