"""Cost of `jaxmps.sweep` per member against one `jaxmps.simulate` run.

The 2-D dam break (spacing 0.0146 m, 518 particles, 160 steps) is run once alone
and as vmapped batches of 4, 8 and 16 viscosities (one chunk each). Run times exclude
compilation (each program is called twice; the second call is timed: for the single
run `_common.time_compiled`, for a sweep its second call).

Run: python benchmarks/sweep_cost.py  (writes results/sweep_cost_cpu.{json,md})
"""

import json
import os
import pathlib

import jax.numpy as jnp
import numpy as np
from _common import fixed_steps, time_compiled

import jaxmps

HERE = pathlib.Path(__file__).parent


def main():
    case = fixed_steps(jaxmps.scenes.dam_break(spacing=0.0146))
    obs = jaxmps.scenes.observe_probes(case.probes)
    n_steps = 160
    args = (case.scene, case.params, case.state, n_steps, 20, obs)
    single = time_compiled(
        jaxmps.lower_simulate, *args, repeats=1, throw=False
    ).run_s_best
    rows = [dict(batch=1, run_s=single, per_member_s=single, ratio_to_single=1.0)]
    for b in (4, 8, 16):
        nus = jnp.asarray(np.geomspace(1e-6, 1e-2, b), case.params.dt.dtype)
        # The first sweep of a batch shape compiles; time the second.
        jaxmps.sweep(case, {"viscosity": nus}, n_steps, 20, chunk=b)
        res = jaxmps.sweep(case, {"viscosity": nus}, n_steps, 20, chunk=b)
        run = res.wall_time
        rows.append(
            dict(
                batch=b,
                run_s=run,
                per_member_s=run / b,
                ratio_to_single=run / b / single,
            )
        )
    load = os.getloadavg()[0]
    out = HERE / "results" / "sweep_cost_cpu"
    out.with_suffix(".json").write_text(
        json.dumps(dict(rows=rows, load=load), indent=1)
    )
    lines = [
        "| batch | run [s] | per member [s] | per member / single run |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {r['batch']} | {r['run_s']:.3f} | {r['per_member_s']:.3f} | "
        f"{r['ratio_to_single']:.2f} |"
        for r in rows
    ]
    out.with_suffix(".md").write_text(
        "# sweep cost per member (CPU, 2 cores)\n\n"
        + "\n".join(lines)
        + f"\n\n1-min load average at the end: {load:.2f}\n"
    )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
