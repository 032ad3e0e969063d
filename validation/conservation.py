"""Volume and momentum conservation of the standard and high-accuracy schemes.

Two runs per scheme (semi-implicit, float64, l0 = 1 cm):
* the 0.2 m hydrostatic tank at rest for 2 s;
* the 0.4 m x 0.2 m standing wave (A = 2 cm) for 2 s.

Observed every 10 steps:
* water level: the mean over the tank's particle columns of the highest fluid
  particle's centre plus l0/2, minus the initial value of the same measure (a
  volume change per unit width divided by the tank length);
* mean number-density error of the interior fluid (n / n0 - 1 over fluid
  particles that are not on the free surface, n > 0.97 n0): compression;
* net fluid momentum per unit mass, sum(u) / N [m/s] (zero for both set-ups by
  symmetry; walls act on the fluid, so it is not conserved exactly, but a
  spurious drift shows here).

Run: python validation/conservation.py  (writes results/conservation_cpu.{json,md})
"""

import json
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from _common import loadavg, machine_info

import jaxmps
from jaxmps.operators import make_pairs, number_density

jax.config.update("jax_enable_x64", True)
HERE = pathlib.Path(__file__).parent


class Observe(eqx.Module):
    columns: tuple
    spacing: float

    def __call__(self, scene, state):
        fluid = jnp.logical_and(state.active, state.kind == int(jaxmps.Kind.FLUID))
        x, y = state.position[:, 0], state.position[:, 1]
        edges = jnp.asarray(self.columns)
        col = jnp.searchsorted(edges, x) - 1
        tops = (
            jnp.full(len(self.columns) - 1, -jnp.inf)
            .at[col]
            .max(jnp.where(fluid, y, -jnp.inf))
        )
        level = jnp.mean(jnp.where(jnp.isfinite(tops), tops, 0.0)) + 0.5 * self.spacing
        nbrs = jaxmps.neighbours.build(
            scene.grid, state.position, state.active, scene.max_neighbours, scene.r_e
        )
        n = number_density(
            make_pairs(nbrs.index, state.position, scene.weight, scene.r_e)
        )
        inner = fluid & (n > 0.97 * scene.n0)
        compression = jnp.sum(jnp.where(inner, n / scene.n0 - 1, 0.0)) / jnp.sum(inner)
        count = jnp.sum(fluid)
        momentum = jnp.sum(jnp.where(fluid[:, None], state.velocity, 0.0), 0) / count
        return dict(
            time=state.time, level=level, compression=compression, momentum=momentum
        )


def run(case, seconds):
    l0 = case.scene.spacing
    width = float(case.config.get("tank_length", case.config.get("width")))
    observe = Observe(tuple(np.arange(0.0, width + 0.5 * l0, l0).tolist()), l0)
    n = int(seconds / float(case.params.dt)) // 10 * 10
    tr = jaxmps.simulate(
        case.scene, case.params, case.state, n, 10, observe, throw=False
    )
    saved = {k: np.asarray(v) for k, v in tr.saved.items()}
    level = saved["level"] - saved["level"][0]
    return dict(
        successful=bool(tr.result == jaxmps.Result.successful),
        steps=n,
        level_drift_mm=1e3 * float(level[-len(level) // 4 :].mean()),
        level_range_mm=1e3 * float(level.max() - level.min()),
        compression_mean=float(saved["compression"][len(level) // 2 :].mean()),
        compression_final=float(saved["compression"][-1]),
        momentum_max=float(np.abs(saved["momentum"]).max()),
        momentum_final=np.abs(saved["momentum"][-1]).tolist(),
    )


def main():
    rows = []
    for scheme in ("standard", "high_accuracy"):
        cases = {
            "hydrostatic": jaxmps.scenes.hydrostatic(
                spacing=0.01, width=0.2, depth=0.2, scheme=scheme
            ),
            "standing_wave": jaxmps.scenes.standing_wave(
                tank_length=0.4,
                depth=0.2,
                tank_height=0.3,
                amplitude=0.02,
                scheme=scheme,
            ),
        }
        for name, case in cases.items():
            row = dict(scheme=scheme, case=name, **run(case, 2.0))
            print(row, flush=True)
            rows.append(row)
    out = dict(machine=machine_info(), loadavg_1min_end=loadavg(), rows=rows)
    (HERE / "results" / "conservation_cpu.json").write_text(json.dumps(out, indent=2))
    lines = [
        "# Volume and momentum over 2 s (l0 = 1 cm, float64)",
        "",
        "Level drift: mean column-top level over the last quarter minus its initial "
        "value (volume change / tank length); compression: mean n/n0 - 1 of interior "
        "fluid over the second half; momentum: max |sum u / N| over the run.",
        "",
        "| scheme | case | level drift [mm] | level range [mm] "
        "| compression | max abs(mean u) [m/s] | result |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scheme']} | {r['case']} | {r['level_drift_mm']:+.2f} "
            f"| {r['level_range_mm']:.2f} | {100 * r['compression_mean']:+.2f} % "
            f"| {r['momentum_max']:.2e} | {'ok' if r['successful'] else 'failed'} |"
        )
    (HERE / "results" / "conservation_cpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
