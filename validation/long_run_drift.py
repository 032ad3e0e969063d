"""Long-run drift: a hydrostatic tank over 10^5 steps keeps its pressure and volume.

Scene: `jaxmps.scenes.hydrostatic(spacing=0.02, width=0.2, depth=0.2)` (10 x 10
fluid particles), each method's default dt, `--steps` steps (default 100 000) in one
`jaxmps.simulate` call, observed every `--every` steps (default 500):
* bottom pressure error: the `pressure_bottom` probe against rho g (H - l0/2 - y_p),
  y_p the probe particles' mean initial height (as in accuracy_vs_cost.py);
* volume: the `water_level` probe (highest fluid particle near the centre + l0/2)
  minus its initial value, in l0; and the fluid's mean number-density error
  (n / n0 - 1 over interior fluid, n > 0.97 n0), a compression measure;
* max fluid speed (a spurious current or a slow blow-up shows here).
Reported: the means over the first and the last 10 % of the saves and the largest
excursion; the run ends early (and says so) if a result code fires.

Run (~15 min on 2 CPU cores for the three methods, float64):

    python validation/long_run_drift.py
    python validation/long_run_drift.py --steps 20000 --methods explicit

Writes results/long_run_drift_<cpu|gpu>.{json,md}.
"""

import argparse
import json
import sys
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxmps
from jaxmps.operators import make_pairs, number_density

jax.config.update("jax_enable_x64", True)
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _common import compile_timed, loadavg, machine_info, time_calls  # noqa: E402

METHODS = {
    "semi_implicit": dict(solver="semi_implicit"),
    "high_accuracy": dict(solver="semi_implicit", scheme="high_accuracy"),
    "explicit": dict(solver="explicit"),
}


class Observe(eqx.Module):
    probes: tuple

    def __call__(self, scene, state):
        out = jaxmps.scenes.observe_probes(self.probes)(scene, state)
        fluid = jnp.logical_and(state.active, state.kind == int(jaxmps.Kind.FLUID))
        nbrs = jaxmps.neighbours.build(
            scene.grid, state.position, state.active, scene.max_neighbours, scene.r_e
        )
        n = number_density(
            make_pairs(nbrs.index, state.position, scene.weight, scene.r_e)
        )
        inner = fluid & (n > 0.97 * scene.n0)
        out["compression"] = jnp.sum(jnp.where(inner, n / scene.n0 - 1, 0.0)) / (
            jnp.maximum(jnp.sum(inner), 1)
        )
        speed = jnp.sqrt(jnp.sum(state.velocity**2, axis=-1))
        out["max_speed"] = jnp.max(jnp.where(fluid, speed, 0.0))
        out["result"] = (state.result != jaxmps.Result.successful).astype(int)
        return out


def run(method: str, steps: int, every: int) -> dict:
    case = jaxmps.scenes.hydrostatic(
        spacing=0.02, width=0.2, depth=0.2, **METHODS[method]
    )
    l0 = case.scene.spacing
    reference = jaxmps.scenes.hydrostatic_pressure(case)
    args = (case.scene, case.params, case.state, steps, every, Observe(case.probes))
    # One call only (the run is the measurement): its time is the warm-up's.
    compiled, lower_s, compile_s = compile_timed(
        jaxmps.lower_simulate, *args, throw=False
    )
    compile_s += lower_s
    out, run_s, _ = time_calls(lambda: compiled(*args, throw=False), repeats=0)
    s = {k: np.asarray(v, float) for k, v in out.saved.items()}
    good = s["result"] == 0
    last_good = int(np.sum(np.cumprod(good)))
    s = {k: v[:last_good] for k, v in s.items()}
    error = s["pressure_bottom"] / reference - 1
    level = (s["water_level"] - s["water_level"][0]) / l0
    k = max(1, len(error) // 10)
    row = {
        "method": method,
        "capacity": int(case.scene.capacity),
        "dt": float(case.params.dt),
        "steps": steps,
        "steps_done": last_good * every,
        "simulated_s": float(s["time"][-1]) if last_good else 0.0,
        "result": "successful" if last_good == len(good) else "failed",
        "compile_s": compile_s,
        "run_s": run_s,
        "particle_steps_per_s": case.scene.capacity * steps / run_s,
        "p_error_first": float(np.mean(error[:k])),
        "p_error_last": float(np.mean(error[-k:])),
        "p_error_max_abs": float(np.max(np.abs(error))),
        "level_first_l0": float(np.mean(level[:k])),
        "level_last_l0": float(np.mean(level[-k:])),
        "level_max_abs_l0": float(np.max(np.abs(level))),
        "compression_first": float(np.mean(s["compression"][:k])),
        "compression_last": float(np.mean(s["compression"][-k:])),
        "max_speed_last": float(np.mean(s["max_speed"][-k:])),
        "max_speed_max": float(np.max(s["max_speed"])),
        "series": {
            "time": s["time"].tolist(),
            "p_error": error.tolist(),
            "level_l0": level.tolist(),
            "compression": s["compression"].tolist(),
            "max_speed": s["max_speed"].tolist(),
        },
    }
    print(
        f"{method}: {row['result']} {row['steps_done']} steps ({row['simulated_s']:.1f}"
        f" s) p err {row['p_error_first']:+.4f} -> {row['p_error_last']:+.4f} "
        f"level {row['level_last_l0']:+.3f} l0 compression "
        f"{row['compression_first']:+.4f} -> {row['compression_last']:+.4f} "
        f"run {run_s:.0f} s",
        flush=True,
    )
    return row


def markdown(data: dict) -> str:
    m = data["machine"]
    out = [
        "# Long-run drift: hydrostatic tank, 10^5 steps (float64)",
        "",
        f"- machine: {m['platform']}, {m['cpu_model']}, {m['cpu_usable']} usable cores;"
        f" jax {m['jax']}, git {m['git_commit']}",
        f"- 1-min load average {m['loadavg_1min_start']} at start, "
        f"{data['loadavg_end']} at end",
        "- first / last: means over the first and the last 10 % of the saves; "
        "p error: bottom probe vs rho g (H - l0/2 - y_p); level: water-level change "
        "in l0; compression: mean n/n0 - 1 of the interior fluid",
        "",
        "| method | dt [s] | steps (sim. s) | result | p error first -> last "
        "(max abs) | level last (max abs) [l0] | compression first -> last | "
        "max speed last [m/s] | run [s] (compile) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in data["rows"]:
        out.append(
            f"| {r['method']} | {r['dt']:.3g} | {r['steps_done']} "
            f"({r['simulated_s']:.0f}) | {r['result']} | "
            f"{100 * r['p_error_first']:+.2f} -> {100 * r['p_error_last']:+.2f} % "
            f"({100 * r['p_error_max_abs']:.1f} %) | {r['level_last_l0']:+.3f} "
            f"({r['level_max_abs_l0']:.3f}) | {r['compression_first']:+.4f} -> "
            f"{r['compression_last']:+.4f} | {r['max_speed_last']:.2g} | "
            f"{r['run_s']:.0f} ({r['compile_s']:.1f}) |"
        )
    return "\n".join(out) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--every", type=int, default=500)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    out = args.out or HERE / "results" / f"long_run_drift_{jax.default_backend()}"
    info = machine_info()
    rows = [run(m, args.steps, args.every) for m in args.methods]
    data = {"machine": info, "loadavg_end": loadavg(), "rows": rows}
    out.with_suffix(".json").write_text(json.dumps(data, indent=1))
    out.with_suffix(".md").write_text(markdown(data))
    print(markdown(data))


if __name__ == "__main__":
    main()
