"""The `jaxmps` command line (DESIGN.md §4): scenes, run, info, plot."""

import argparse
import json
import sys
from pathlib import Path


def parse_value(text: str):
    """Parse a `--set` value: int, float, None/null, true/false, else the string."""
    lowered = text.strip().lower()
    if lowered in ("none", "null"):
        return None
    if lowered in ("true", "false"):
        return lowered == "true"
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    return text


def _parse_overrides(items: list[str]) -> dict:
    overrides = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--set expects NAME=VALUE, got {item!r}.")
        overrides[name.strip()] = parse_value(value)
    return overrides


def _cmd_scenes(args) -> int:
    from . import scenes

    for name, defaults in scenes.available().items():
        print(name)
        width = max(len(k) for k in defaults)
        for key, value in defaults.items():
            shown = "(derived)" if value is None else repr(value)
            print(f"  {key:<{width}}  {shown}")
    return 0


def _cmd_run(args) -> int:
    import jax

    if args.x64:
        jax.config.update("jax_enable_x64", True)
    from . import scenes
    from ._driver import run
    from .io import read_run

    try:
        overrides = _parse_overrides(args.set)
    except ValueError as e:
        print(f"jaxmps run: error: {e}", file=sys.stderr)
        return 2
    restart = args.restart is not None
    source = Path(args.restart) if args.restart else None  # --restart RUN.h5
    if args.out:
        out = Path(args.out)
    else:
        out = source if source is not None else Path(f"{args.scene}.h5")
    source = out if restart and source is None else source
    scene = args.scene
    if restart:
        if not source.exists():
            print(
                f"jaxmps run: error: --restart: '{source}' does not exist.",
                file=sys.stderr,
            )
            return 2
        try:
            data = read_run(source)
        except ValueError as e:
            print(f"jaxmps run: error: {e}", file=sys.stderr)
            return 2
        scene = str(data.attrs["scene"])
        overrides = {**data.config, **overrides}
    try:
        case = scenes.build(scene, **overrides)
    except (ValueError, TypeError) as e:
        print(f"jaxmps run: error: {e}", file=sys.stderr)
        return 2
    n = int(case.state.active.sum())
    print(
        f"jaxmps: {case.name}, {n} particles, dt={float(case.params.dt):.4g} s, "
        f"t_end={args.t_end if args.t_end is not None else case.t_end:g} s"
        + (f" (restart from {source})" if restart else "")
    )
    try:
        result = run(
            case,
            t_end=args.t_end,
            out=out,
            save_every=args.save_every,
            progress=not args.quiet,
            restart_from=source,
        )
    except RuntimeError as e:
        print(f"jaxmps run: {e}", file=sys.stderr)
        print(f"Wrote what was computed to {out} and {out.with_suffix('.xdmf')}")
        return 1
    print(
        f"Done: {result.n_steps} steps in {result.wall_time:.1f} s "
        f"(t = {float(result.state.time):.4g} s)."
    )
    print(f"Wrote {out} and {out.with_suffix('.xdmf')} (open the .xdmf in ParaView).")
    return 0


def _cmd_info(args) -> int:
    from .io import read_run

    try:
        data = read_run(args.file)
    except (ValueError, FileNotFoundError) as e:
        print(f"jaxmps info: error: {e}", file=sys.stderr)
        return 2
    a = data.attrs
    print(
        f"{data.path}: jaxmps run file (format_version {a.get('format_version')}, "
        f"written by jaxmps {a.get('jaxmps_version')})"
    )
    print(
        f"  scene    {a.get('scene')}  (dim {a.get('dim')}, "
        f"spacing {a.get('spacing'):g} m, dt {a.get('dt'):.4g} s)"
    )
    kind = data.particles["kind"]
    counts = ", ".join(
        f"{name} {int((kind == k).sum())}"
        for k, name in enumerate(
            ["fluid", "wall", "dummy", "rigid", "elastic", "sediment"]
        )
        if (kind == k).any()
    )
    print(f"  particles {len(kind)} ({counts})")
    times = data.frames.get("time")
    if times is not None and len(times):
        print(
            f"  frames   {len(times)}, t = {times[0]:.4g} ... {times[-1]:.4g} s, "
            f"steps {int(data.frames['step'][0])} ... {int(data.frames['step'][-1])}"
        )
    else:
        print("  frames   0")
    names = [k for k in data.probes if k != "time"]
    print(
        f"  probes   {len(data.probes.get('time', []))} rows: {', '.join(names) or '-'}"
    )
    if data.bodies:
        count = data.bodies["centre"].shape[1]
        print(f"  bodies   {count} rigid, per frame: {', '.join(sorted(data.bodies))}")
    if data.state:
        from ._result import Result, result_from_code

        value = int(data.state["result"])
        status = "successful" if value == 0 else Result[result_from_code(value)]
        print(
            f"  state    t = {float(data.state['time']):.4g} s, step "
            f"{int(data.state['step'])}, result: {status}"
        )
    print(f"  config   {json.dumps(data.config, sort_keys=True)}")
    return 0


def _cmd_plot(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .io import read_run

    try:
        data = read_run(args.file)
    except (ValueError, FileNotFoundError) as e:
        print(f"jaxmps plot: error: {e}", file=sys.stderr)
        return 2
    times = data.frames.get("time")
    if times is None or not len(times):
        print(f"jaxmps plot: error: '{args.file}' holds no frames.", file=sys.stderr)
        return 2
    index = (
        len(times) - 1
        if args.time is None
        else int(np.argmin(np.abs(times - args.time)))
    )
    position = data.frames["position"][index]
    pressure = data.frames["pressure"][index]
    active = data.frames["active"][index]
    kind = data.particles["kind"]
    fluid = active & (kind == 0)
    solid = active & (kind != 0)
    fig, ax = plt.subplots(figsize=(8, 5), dpi=120)
    size = max(1.0, 4000.0 / max(1, len(position)))
    ax.scatter(position[solid, 0], position[solid, -1], s=size, c="0.6", lw=0)
    sc = ax.scatter(
        position[fluid, 0],
        position[fluid, -1],
        s=size,
        c=pressure[fluid],
        cmap="viridis",
        lw=0,
    )
    fig.colorbar(sc, ax=ax, label="pressure [Pa]")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]" if position.shape[1] == 3 else "y [m]")
    ax.set_title(f"{data.attrs.get('scene')}  t = {times[index]:.4g} s")
    out = Path(args.out) if args.out else Path(args.file).with_suffix(".png")
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)
    print(f"Wrote {out}")
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxmps", description="Differentiable MPS particle solver in JAX."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("scenes", help="list scenes and their parameters with defaults")
    p = sub.add_parser("run", help="run a scene and write RUN.h5 + RUN.xdmf")
    p.add_argument("scene", nargs="?", default="dam_break")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a scene parameter (repeatable)",
    )
    p.add_argument("--t-end", type=float, default=None, help="simulated time [s]")
    p.add_argument(
        "--save-every",
        type=float,
        default=None,
        help="simulated time between saved frames [s]",
    )
    p.add_argument("--out", default=None, help="run file (default SCENE.h5)")
    p.add_argument("--x64", action="store_true", help="run in float64")
    p.add_argument(
        "--restart",
        nargs="?",
        const="",
        default=None,
        metavar="RUN.h5",
        help="continue RUN.h5 (default: --out) from its last good state, appending "
        "to it (or writing --out when given); --set changes settings",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p = sub.add_parser("info", help="what a run file holds")
    p.add_argument("file")
    p = sub.add_parser("plot", help="particle snapshot coloured by pressure")
    p.add_argument("file")
    p.add_argument(
        "--time", type=float, default=None, help="nearest frame (default last)"
    )
    p.add_argument("--out", default=None, help="PNG file (default RUN.png)")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `jaxmps` command.

    Args:
        argv: arguments (default `sys.argv[1:]`).

    Returns:
        0 on success.

    Raises:
        SystemExit: with code 1 if a run failed, 2 for bad usage (unknown scene or
            parameter, unreadable run file), as argparse does for bad options. The
            message is printed to stderr, without a traceback.
    """
    args = _parser().parse_args(argv)
    commands = {
        "scenes": _cmd_scenes,
        "run": _cmd_run,
        "info": _cmd_info,
        "plot": _cmd_plot,
    }
    code = commands[args.command](args)
    if code:
        raise SystemExit(code)
    return 0


if __name__ == "__main__":
    sys.exit(main())
