"""The `jaxmps` command line (DESIGN.md §4): scenes, run, info, plot."""

import argparse
import json
import math
import sys
import warnings
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


class UsageError(ValueError):
    """A refused command line, printed as one line (exit code 2)."""


def _start_jax(x64: bool):
    """Import JAX and start its backend, refusing (UsageError) a platform that
    cannot start, e.g. JAX_PLATFORMS=cuda on a machine without a GPU."""
    import os

    import jax

    if x64:
        jax.config.update("jax_enable_x64", True)
    try:
        jax.devices()
    except Exception as e:  # noqa: BLE001 - JAX raises several types here
        platforms = os.environ.get("JAX_PLATFORMS")
        setting = f" (JAX_PLATFORMS={platforms})" if platforms else ""
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise UsageError(
            f"JAX cannot start its backend{setting}: {first}. Unset JAX_PLATFORMS "
            "or set it to a platform this machine has (e.g. cpu)."
        ) from None
    return jax


def _cmd_run(args) -> int:
    from ._driver import check_output

    overrides = _parse_overrides(args.set)
    for name in ("t_end", "save_every"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            flag = "--" + name.replace("_", "-")
            raise UsageError(f"{flag} must be positive and finite [s], got {value!r}.")
    restart = args.restart is not None
    source = Path(args.restart) if args.restart else None  # --restart RUN.h5
    if args.out:
        out = Path(args.out)
    else:
        out = source if source is not None else Path(f"{args.scene}.h5")
    source = out if restart and source is None else source
    append = restart and out.resolve() == source.resolve()
    # The output is checked before any work, and before JAX starts.
    check_output(out, overwrite=args.overwrite, append=append, name="--out")
    if restart and not source.exists():
        raise UsageError(f"--restart: '{source}' does not exist.")
    _start_jax(args.x64)
    from . import scenes
    from ._driver import run
    from .io import read_run

    scene = args.scene
    if restart:
        data = read_run(source)
        scene = str(data.attrs["scene"])
        overrides = {**data.config, **overrides}
    case = scenes.build(scene, **overrides)
    n = int(case.state.active.sum())
    dt = float(case.params.dt)
    steps = (
        f"adaptive dt <= {dt:.4g} s"
        if case.scene.time_step is not None
        else f"dt={dt:.4g} s"
    )
    print(
        f"jaxmps: {case.name}, {n} particles, {steps}, "
        f"t_end={args.t_end if args.t_end is not None else case.t_end:g} s"
        + (f" (restart from {source})" if restart else "")
    )
    try:
        with warnings.catch_warnings():
            # The escaped particles are reported below, in the CLI's words.
            warnings.filterwarnings("ignore", message=".*left the domain")
            result = run(
                case,
                t_end=args.t_end,
                out=out,
                save_every=args.save_every,
                progress=not args.quiet,
                restart_from=source,
                overwrite=args.overwrite,
                max_steps_per_save=args.max_steps_per_save,
            )
    except RuntimeError as e:
        print(f"jaxmps run: {e}", file=sys.stderr)
        print(f"Wrote what was computed to {out} and {out.with_suffix('.xdmf')}")
        return 1
    except KeyboardInterrupt as e:
        signum = getattr(e, "signal", 2)
        text = str(e) or "interrupted"
        print(
            f"jaxmps run: {text}; continue with `jaxmps run --restart {out}`.",
            file=sys.stderr,
        )
        return 128 + signum
    escaped = int(result.state.escaped)
    if escaped:
        print(
            f"{escaped} fluid particle(s) left the domain (spray, water over a "
            f"wall) and were taken out of the run (limit {case.scene.escape_limit}: "
            "the `escape_limit` setting)."
        )
    print(
        f"Done: {result.n_steps} steps in {result.wall_time:.1f} s "
        f"(t = {float(result.state.time):.4g} s)."
    )
    print(f"Wrote {out} and {out.with_suffix('.xdmf')} (open the .xdmf in ParaView).")
    return 0


def _cmd_info(args) -> int:
    from .io import read_run

    data = read_run(args.file)
    try:
        return _describe(data)
    except (KeyError, IndexError, TypeError) as e:
        raise UsageError(
            f"'{args.file}' is a damaged run file: {type(e).__name__} {e} while "
            "describing it."
        ) from None


def _describe(data) -> int:
    """Print what a run file holds."""
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
        import numpy as np

        low, high = data.frames.get("dt_min"), data.frames.get("dt_max")
        if low is not None and np.any(np.isfinite(low)):
            print(
                f"  dt       {np.nanmin(low):.4g} ... {np.nanmax(high):.4g} s, "
                f"{int(np.sum(data.frames['rejected']))} steps taken again"
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
        escaped = int(data.state.get("escaped", 0))
        print(
            f"  state    t = {float(data.state['time']):.4g} s, step "
            f"{int(data.state['step'])}, result: {status}"
            + (f", {escaped} fluid particles left the domain" if escaped else "")
        )
    print(f"  config   {json.dumps(data.config, sort_keys=True)}")
    return 0


def _cmd_plot(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .io import read_run

    data = read_run(args.file)
    times = data.frames.get("time")
    if times is None or not len(times):
        raise UsageError(f"'{args.file}' holds no frames.")
    if args.time is None:
        index = len(times) - 1
    elif not times[0] - 1e-9 <= args.time <= times[-1] + 1e-9:
        raise UsageError(
            f"--time {args.time!r} lies outside the run's frames, "
            f"t = {times[0]:.6g} ... {times[-1]:.6g} s."
        )
    else:
        index = int(np.argmin(np.abs(times - args.time)))
    try:
        position = data.frames["position"][index]
        pressure = data.frames["pressure"][index]
        active = data.frames["active"][index]
        kind = data.particles["kind"]
        fluid = active & (kind == 0)
    except (KeyError, IndexError, ValueError) as e:
        raise UsageError(
            f"'{args.file}' is a damaged run file: its frames do not fit together "
            f"({type(e).__name__}: {e})."
        ) from None
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
    if out.is_dir():
        plt.close(fig)
        raise UsageError(f"--out '{out}' is a directory; name an image file in it.")
    try:
        fig.savefig(out, bbox_inches="tight")
    finally:
        plt.close(fig)
    print(f"Wrote {out}")
    return 0


_RUN_FILES = """\
run files: --out must end in .h5 or .hdf5 (the ParaView sidecar is the same name
with .xdmf). An existing file is refused unless --overwrite is given (--restart
appends to its own file). A new file is written as .NAME.partial and moved to
NAME once its first frame exists; from then on it holds every frame written and
the state to restart from, whatever stops the run: a failure, a full disk,
Ctrl-C (SIGINT) or SIGTERM (the chunk being computed is written first; a second
signal stops at once)."""


def _parser() -> argparse.ArgumentParser:
    debug = argparse.ArgumentParser(add_help=False)
    debug.add_argument(
        "--debug",
        action="store_true",
        default=argparse.SUPPRESS,
        help="show the Python traceback of any error",
    )
    parser = argparse.ArgumentParser(
        prog="jaxmps",
        description="Differentiable MPS particle solver in JAX.",
        parents=[debug],
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser(
        "scenes", help="list scenes and their parameters with defaults", parents=[debug]
    )
    p = sub.add_parser(
        "run",
        help="run a scene and write RUN.h5 + RUN.xdmf",
        parents=[debug],
        epilog=_RUN_FILES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
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
    p.add_argument(
        "--out", default=None, help="run file, .h5 or .hdf5 (default SCENE.h5)"
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing --out (kept until the new run has its first frame)",
    )
    p.add_argument(
        "--max-steps-per-save",
        type=int,
        default=None,
        metavar="N",
        help="the most step attempts between two saves (default: 20 x the steps "
        "of the largest dt in a save interval, + 100)",
    )
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
    p = sub.add_parser("info", help="what a run file holds", parents=[debug])
    p.add_argument("file")
    p = sub.add_parser(
        "plot", help="particle snapshot coloured by pressure", parents=[debug]
    )
    p.add_argument("file")
    p.add_argument(
        "--time", type=float, default=None, help="nearest frame (default last)"
    )
    p.add_argument("--out", default=None, help="PNG file (default RUN.png)")
    return parser


# Errors a user's input can cause: one line, exit code 2.
_USER_ERRORS = (ValueError, OverflowError, OSError, TypeError)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `jaxmps` command.

    Args:
        argv: arguments (default `sys.argv[1:]`).

    Returns:
        0 on success.

    Raises:
        SystemExit: with code 2 for bad usage (an unknown scene or parameter, a
            value out of range, an output file that must not be written, an
            unreadable run file: any ValueError, OverflowError, OSError or
            TypeError), printed as one line `jaxmps CMD: error: ...`, as argparse
            does for bad options; 1 if a run failed (its message), or for an
            internal error (one line asking for a report); 128 + the signal's
            number for a run stopped by SIGINT or SIGTERM. `--debug` shows the
            traceback of any error instead.
    """
    args = _parser().parse_args(argv)
    commands = {
        "scenes": _cmd_scenes,
        "run": _cmd_run,
        "info": _cmd_info,
        "plot": _cmd_plot,
    }
    debug = getattr(args, "debug", False)
    try:
        code = commands[args.command](args)
    except KeyboardInterrupt:
        if debug:
            raise
        print(f"jaxmps {args.command}: interrupted.", file=sys.stderr)
        code = 130
    except _USER_ERRORS as e:
        if debug:
            raise
        print(f"jaxmps {args.command}: error: {_one_line(e)}", file=sys.stderr)
        code = 2
    except Exception as e:  # noqa: BLE001 - a bug: one line unless --debug
        if debug:
            raise
        print(
            f"jaxmps {args.command}: internal error, please report it with the "
            f"output of the same command with --debug: {type(e).__name__}: "
            f"{_one_line(e)}",
            file=sys.stderr,
        )
        code = 1
    if code:
        raise SystemExit(code)
    return 0


def _one_line(error: BaseException) -> str:
    """An exception's message on one line (the type's name if it has none)."""
    text = " ".join(str(error).split())
    return text or type(error).__name__


if __name__ == "__main__":
    sys.exit(main())
