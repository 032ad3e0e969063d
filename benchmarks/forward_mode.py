"""Forward against reverse mode: the derivative of an adaptive rollout with respect
to one or a few Params fields, its run time, compile time and memory.

`simulate(..., autodiff="forward")` runs each save's adaptive steps in a plain
while loop that carries the tangents along (`jax.jvp`; `jax.jacfwd` for several
fields at once, a vmap of JVPs); the default, reverse mode, runs it in a
checkpointed while loop (16 stored states per save) and the saves under
`jax.checkpoint`. Both give the same derivative (tests/test_gradients.py).

For each rollout length (`--times`: the number of saves, 0.02 s apart, of the dam
break with its own adaptive steps) this measures, each program compiled apart
from running (`_common.time_compiled`):
- the run alone (no derivative);
- forward mode: the JVP along viscosity, and `jacfwd` over viscosity and density;
- reverse mode: `value_and_grad` with respect to viscosity and density (reverse
  mode pays the same for one field or all of them);
and for each its compile time, best run time, ratio to the run alone, and XLA's
static temporary memory (`Compiled.memory_analysis()`).

Run: python benchmarks/forward_mode.py [--spacing 0.02] [--saves 5 20]
(writes results/forward_mode_<backend>.{json,md})
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp
from _common import time_compiled, write_rows

import jaxmps

FIELDS = ("viscosity", "density")


def observe_time(scene, state):
    return state.time


def loss(values, case, times, autodiff):
    params = case.params
    for name, v in zip(FIELDS, values):
        params = eqx.tree_at(lambda p, n=name: getattr(p, n), params, v)
    out = jaxmps.simulate(
        case.scene,
        params,
        case.state,
        times=times,
        observe=observe_time,
        throw=False,
        autodiff=autodiff,
    )
    fluid = out.state.kind == int(jaxmps.Kind.FLUID)
    return jnp.sum(jnp.where(fluid, out.state.position[:, 0], 0.0)) / jnp.sum(fluid)


def programs(case, times):
    x = jnp.stack([jnp.asarray(getattr(case.params, f)) for f in FIELDS])
    one = jnp.zeros_like(x).at[0].set(1.0)
    return {
        "run alone": (jax.jit(lambda x: loss(x, case, times, "reverse")), (x,)),
        "forward, 1 field (jvp)": (
            jax.jit(
                lambda x, t: jax.jvp(
                    lambda y: loss(y, case, times, "forward"), (x,), (t,)
                )
            ),
            (x, one),
        ),
        "forward, 2 fields (jacfwd)": (
            jax.jit(jax.jacfwd(lambda y: loss(y, case, times, "forward"))),
            (x,),
        ),
        "reverse, 2 fields (grad)": (
            jax.jit(jax.value_and_grad(lambda y: loss(y, case, times, "reverse"))),
            (x,),
        ),
    }


def temp_mib(compiled) -> float | None:
    try:
        analysis = compiled.memory_analysis()
    except Exception:  # noqa: BLE001
        return None
    return None if analysis is None else analysis.temp_size_in_bytes / 2**20


def markdown(info, rows) -> str:
    lines = [
        "# Forward against reverse mode: derivatives of an adaptive rollout",
        "",
        f"Machine: {info.get('cpu_model') or '?'}, {info.get('cpu_usable')} CPUs; "
        f"dtype {info.get('dtype')}; git {info.get('git_commit')}; "
        "`benchmarks/forward_mode.py`. Dam break, its adaptive steps, saves 0.02 s "
        "apart; loss: the fluid's mean final x. Run times: best of the timed calls "
        "after an untimed one; temp: XLA's static temporary buffers.",
        "",
        "| saves | particles | program | compile [s] | run [s] | / run alone | "
        "temp [MiB] | derivative |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        temp = "-" if r["temp_mib"] is None else f"{r['temp_mib']:.1f}"
        lines.append(
            f"| {r['saves']} | {r['particles']} | {r['program']} | "
            f"{r['compile_s']:.1f} | {r['run_s']:.2f} | {r['ratio']:.2f} | {temp} | "
            f"{r['derivative']} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacing", type=float, default=0.02)
    parser.add_argument("--saves", type=int, nargs="+", default=[5, 20])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--x64", action="store_true")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", args.x64)
    case = jaxmps.scenes.dam_break(spacing=args.spacing)
    rows = []
    for saves in args.saves:
        times = jnp.arange(1, saves + 1) * 0.02
        alone = None
        for name, (fn, call_args) in programs(case, times).items():
            timed = time_compiled(fn.lower, *call_args, repeats=args.repeats)
            alone = alone or timed.run_s_best
            out = timed.output
            derivative = out[1] if isinstance(out, tuple) else out
            if name == "run alone":
                derivative = None
            rows.append(
                dict(
                    saves=saves,
                    particles=int(case.state.active.sum()),
                    program=name,
                    compile_s=timed.trace_lower_s + timed.compile_s,
                    run_s=timed.run_s_best,
                    ratio=timed.run_s_best / alone,
                    temp_mib=temp_mib(timed.compiled),
                    derivative="-"
                    if derivative is None
                    else " ".join(f"{float(v):.6g}" for v in jnp.ravel(derivative)),
                )
            )
            print(rows[-1], flush=True)
    write_rows("forward_mode", args.out, rows, markdown)


if __name__ == "__main__":
    main()
