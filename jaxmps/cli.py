"""The `jaxmps` command line: scenes, run, sweep, info, plot."""

import argparse
import json
import math
import os
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


_DEFAULT_SCENE = "dam_break"


class UsageError(ValueError):
    """A refused command line, printed as one line (exit code 2)."""


def _start_jax(x64: bool, platform_only: bool = False):
    """Import JAX and start its backend, refusing (UsageError) a platform that
    cannot start, e.g. JAX_PLATFORMS=cuda on a machine without a GPU. With
    `platform_only` the backend is left to start later (a multi-process run
    starts it after joining the other processes)."""
    import jax

    if x64:
        jax.config.update("jax_enable_x64", True)
    if platform_only:
        return jax
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
    _check_times(args)
    restart = args.restart is not None
    source = Path(args.restart) if args.restart else None  # --restart RUN.h5
    if args.out:
        out = Path(args.out)
    else:
        out = (
            source if source is not None else Path(f"{args.scene or _DEFAULT_SCENE}.h5")
        )
    source = out if restart and source is None else source
    append = restart and out.resolve() == source.resolve()
    # The output is checked before any work, and before JAX starts.
    check_output(out, overwrite=args.overwrite, append=append, name="--out")
    if restart and not source.exists():
        raise UsageError(f"--restart: '{source}' does not exist.")
    _start_jax(args.x64)
    from . import scenes
    from ._driver import resumed_end, run
    from .io import read_run

    scene = args.scene or _DEFAULT_SCENE
    t_end = args.t_end
    if restart:
        data = read_run(source)
        scene = str(data.attrs["scene"])
        if args.scene is not None and args.scene != scene:
            raise UsageError(
                f"--restart: '{source}' is a run of '{scene}', not '{args.scene}'; "
                "leave the scene out to continue it, or start a new run without "
                "--restart."
            )
        overrides = {**scenes.stored_settings(scene, data.config), **overrides}
    case = scenes.build(scene, **overrides)
    if restart and t_end is None:
        t_end = resumed_end(case, source)
    n = int(case.state.active.sum())
    dt = float(case.params.dt)
    steps = (
        f"adaptive dt <= {dt:.4g} s"
        if case.scene.time_step is not None
        else f"dt={dt:.4g} s"
    )
    print(
        f"jaxmps: {case.name}, {n} particles, {steps}, "
        f"t_end={t_end if t_end is not None else case.t_end:g} s"
        + (f" (restart from {source})" if restart else "")
    )
    try:
        with warnings.catch_warnings():
            # The escaped particles are reported below, in the CLI's words.
            warnings.filterwarnings("ignore", message=".*left the domain")
            result = run(
                case,
                t_end=t_end,
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
        then = (
            f"continue with `jaxmps run --restart {out}`"
            if out.exists()
            else f"stopped before its first frame, so no '{out}' was written"
        )
        print(f"jaxmps run: {text}; {then}.", file=sys.stderr)
        if not hasattr(e, "signal"):
            # A second signal stopped the run at once, possibly inside XLA's
            # compiler, whose threads then crash the interpreter's shutdown
            # (a segmentation fault): the file is closed, so leave now.
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(128 + signum)
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


def _check_times(args) -> None:
    """--t-end and --save-every: positive and finite when given (UsageError)."""
    for name in ("t_end", "save_every"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            flag = "--" + name.replace("_", "-")
            raise UsageError(f"{flag} must be positive and finite [s], got {value!r}.")
    most = getattr(args, "max_steps_per_save", None)
    if most is not None and not most >= 1:
        raise UsageError(f"--max-steps-per-save must be at least 1, got {most!r}.")


def _parse_vary(items: list[str]) -> dict:
    """`--vary NAME=V1,V2,...` items as {name: [values]} (UsageError if malformed)."""
    varied = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name or not text.strip():
            raise UsageError(f"--vary expects NAME=V1,V2,..., got {item!r}.")
        if name in varied:
            raise UsageError(f"--vary names {name!r} twice.")
        values = [parse_value(v) for v in text.split(",")]
        bad = [v for v in values if isinstance(v, (str, bool)) or v is None]
        if bad:
            raise UsageError(
                f"--vary {name}: values must be numbers, got {bad[0]!r} in {item!r}."
            )
        varied[name] = values
    if not varied:
        raise UsageError("jaxmps sweep needs at least one --vary NAME=V1,V2,...")
    return varied


def _start_processes(args, jax) -> None:
    """Join a multi-process run (`--coordinator`, `--num-processes`,
    `--process-id`) with a bounded wait for the coordinator."""
    given = [args.coordinator, args.num_processes, args.process_id]
    if all(v is None for v in given):
        return
    if any(v is None for v in given):
        raise UsageError(
            "--coordinator, --num-processes and --process-id go together "
            "(one process per host, the same --coordinator HOST:PORT for all)."
        )
    if not (args.num_processes >= 1 and 0 <= args.process_id < args.num_processes):
        raise UsageError(
            f"--process-id must lie in [0, --num-processes), got {args.process_id} "
            f"of {args.num_processes}."
        )
    from ._devices import start_processes

    print(
        f"jaxmps sweep: process {args.process_id} of {args.num_processes} joining "
        f"the run at {args.coordinator} (waiting up to {args.timeout:g} s)",
        file=sys.stderr,
    )
    start_processes(args.coordinator, args.num_processes, args.process_id, args.timeout)


def _cmd_sweep(args) -> int:
    from ._sweep_files import check_folder

    overrides = _parse_overrides(args.set)
    varied = _parse_vary(args.vary)
    if "gravity" in varied:
        raise UsageError(
            "--vary gravity: Params.gravity is a vector (one component per axis), "
            "which --vary cannot give; run one sweep per --set gravity=..., or "
            "sweep it from Python: jaxmps.sweep(case, {'gravity': [[0, -9.81], "
            "[0, -5.0]]}, ...)."
        )
    _check_times(args)
    args.scene = args.scene or _DEFAULT_SCENE
    out = check_folder(args.out or f"{args.scene}_sweep", args.overwrite)
    jax = _start_jax(args.x64, platform_only=args.coordinator is not None)
    _start_processes(args, jax)
    from . import scenes
    from ._devices import member_mesh
    from ._sweep_files import grid, sweep_run

    case = scenes.build(args.scene, **overrides)
    values = grid(varied)
    mesh = member_mesh(devices=args.devices)
    members = len(next(iter(values.values())))
    lead = jax.process_index() == 0
    if lead:
        print(
            f"jaxmps: sweep of {case.name}, {members} members "
            f"({' x '.join(f'{len(v)} {k}' for k, v in varied.items())}) on "
            f"{mesh.devices.size} device(s) in {jax.process_count()} process(es), "
            f"t_end={args.t_end if args.t_end is not None else case.t_end:g} s"
        )
    try:
        result = sweep_run(
            case,
            values,
            t_end=args.t_end,
            out=out,
            save_every=args.save_every,
            mesh=mesh,
            max_steps_per_save=args.max_steps_per_save,
            overwrite=args.overwrite,
            progress=lead and not args.quiet,
        )
    except KeyboardInterrupt as e:
        signum = getattr(e, "signal", 2)
        print(f"jaxmps sweep: {e or 'interrupted'}", file=sys.stderr)
        return 128 + signum
    failed = [m for m in result.index["members"] if m.get("code", 0)]
    if lead:
        print(
            f"Done: {members - len(failed)} of {members} members successful in "
            f"{result.wall_time:.1f} s. Wrote {out}/ (index {out}/sweep.json)."
        )
        for m in failed:
            reached = m["t_reached"]
            values = ", ".join(f"{k}={float(v):g}" for k, v in m["values"].items())
            print(f"  {m['file']} ({values}): {m['result']} at t={reached:.4g} s")
    return 1 if failed else 0


def _cmd_info(args) -> int:
    from .io import read_run

    path = Path(args.file)
    if path.is_dir() or path.suffix == ".json":
        return _describe_sweep(path)
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
    import numpy as np

    a = data.attrs
    print(
        f"{data.path}: jaxmps run file (format_version {a.get('format_version')}, "
        f"written by jaxmps {a.get('jaxmps_version')})"
    )
    print(
        f"  scene    {a.get('scene')}  (dim {a.get('dim')}, "
        f"spacing {a.get('spacing'):g} m, dt {a.get('dt'):.4g} s)"
    )
    _describe_status(data)
    kind = data.particles["kind"]
    # Active particles of the last state (a pool's free slots are fluid slots
    # that hold no particle), or of the last frame.
    active = data.state.get("active")
    if active is None and len(data.frames.get("active", ())):
        active = data.frames["active"][-1]
    active = np.ones(len(kind), bool) if active is None else np.asarray(active, bool)
    counts = ", ".join(
        f"{name} {int((active & (kind == k)).sum())}"
        for k, name in enumerate(
            ["fluid", "wall", "dummy", "rigid", "elastic", "sediment"]
        )
        if (active & (kind == k)).any()
    )
    free = len(kind) - int(active.sum())
    pool = f"; {free} free slots of {len(kind)}" if free else ""
    print(f"  particles {int(active.sum())} ({counts}{pool})")
    times = data.frames.get("time")
    if times is not None and len(times):
        print(
            f"  frames   {len(times)}, t = {times[0]:.4g} ... {times[-1]:.4g} s, "
            f"steps {int(data.frames['step'][0])} ... {int(data.frames['step'][-1])}"
        )
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
        # Each body model saves its own fields (`frame_fields`); rigid bodies
        # are counted by their centres.
        rigid = data.bodies.get("centre")
        count = "" if rigid is None else f"{rigid.shape[1]} rigid, "
        print(f"  bodies   {count}per frame: {', '.join(sorted(data.bodies))}")
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


def _describe_status(data) -> None:
    """The run's line: how it ended and the end it was asked for (files written
    before these were recorded have no such line)."""
    a = data.attrs
    status = a.get("status")
    if status is None:
        return
    asked = f" (asked for t_end = {a['t_end']:g} s)" if "t_end" in a else ""
    message = a.get("status_message") or ""
    line = f"  run      {status}{asked}" + (f": {message}" if message else "")
    if status in ("interrupted", "running"):
        line += f"; continue with `jaxmps run --restart {data.path}`"
    print(line)


def _describe_sweep(path: Path) -> int:
    """Print what a sweep's folder (or its index) holds: a line per member."""
    from ._sweep_files import read_index

    index = read_index(path)
    members = index.get("members", [])
    ok = sum(1 for m in members if m.get("result") == "successful")
    print(
        f"{path}: jaxmps sweep of {index.get('scene')} (written by jaxmps "
        f"{index.get('jaxmps_version')}), {len(members)} members, {ok} successful, "
        f"t_end {index.get('t_end')} s, on {index.get('devices')} device(s)"
    )
    if "status" in index:
        print(f"  sweep    {index['status']}")
    varied = index.get("varied", [])
    print(f"  varied   {', '.join(varied)}")
    print(f"  config   {json.dumps(index.get('config'), sort_keys=True)}")
    for m in members:
        values = ", ".join(f"{k}={m['values'][k]:g}" for k in varied)
        state = m.get("result", "not run")
        reached = m.get("t_reached")
        at = "" if reached is None else f" t={reached:.4g} s, {m.get('steps')} steps"
        print(f"  {m['file']}  {values}  {state}{at}")
    return 0


def _cmd_plot(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .io import read_run

    if Path(args.file).is_dir() or Path(args.file).suffix == ".json":
        raise UsageError(
            f"'{args.file}' is a sweep's folder (or index), not a run file: plot "
            "one member's file, e.g. `jaxmps plot FOLDER/member_000.h5` "
            "(`jaxmps info FOLDER` lists them)."
        )
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
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, bbox_inches="tight")
    except OSError as e:
        raise UsageError(
            f"--out '{out}' cannot be written: {e.strerror or e}."
        ) from None
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
    _scene_and_times(p)
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
    _sweep_parser(sub, debug)
    p = sub.add_parser(
        "info", help="what a run file or a sweep's folder holds", parents=[debug]
    )
    p.add_argument("file", help="a run file, or a sweep's folder (or its sweep.json)")
    p = sub.add_parser(
        "plot", help="particle snapshot coloured by pressure", parents=[debug]
    )
    p.add_argument("file")
    p.add_argument(
        "--time", type=float, default=None, help="nearest frame (default last)"
    )
    p.add_argument("--out", default=None, help="PNG file (default RUN.png)")
    return parser


_SWEEP = """\
A sweep runs the scene once per member as one vmapped batch, split over the
devices (--devices, default all). With several --vary, every combination runs.
It writes FOLDER/member_000.h5, ... (each a run file as `jaxmps run` writes) and
FOLDER/sweep.json, the index: the varied values, each member's file, result and
time reached (`jaxmps info FOLDER`). A failed member keeps its frames to the
failure; the others go on; the exit code is 1 if any member failed.

Several processes (one per host of a cluster, or several on one machine), each
with its devices, run one sweep together: start the same command in each with
--coordinator HOST:PORT (process 0's host and a free port), --num-processes N and
its own --process-id; process 0 writes the files."""


def _scene_and_times(p) -> None:
    """The arguments `run` and `sweep` share: the scene, its settings, the times."""
    # None: dam_break, or with --restart the file's scene.
    p.add_argument("scene", nargs="?", default=None)
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


def _sweep_parser(sub, debug) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a scene once per parameter value, one vmapped batch over devices",
        parents=[debug],
        epilog=_SWEEP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _scene_and_times(p)
    p.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="NAME=V1,V2,...",
        help="a Params field and its values (repeatable: every combination)",
    )
    p.add_argument("--out", default=None, help="folder (default SCENE_sweep)")
    p.add_argument(
        "--overwrite", action="store_true", help="replace the sweep in --out"
    )
    p.add_argument(
        "--devices",
        type=int,
        default=None,
        metavar="N",
        help="split the members over the first N devices (default: all)",
    )
    p.add_argument(
        "--max-steps-per-save",
        type=int,
        default=None,
        metavar="N",
        help="the most step attempts between two saves",
    )
    p.add_argument("--x64", action="store_true", help="run in float64")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--coordinator",
        default=None,
        metavar="HOST:PORT",
        help="multi-process run: process 0's address",
    )
    p.add_argument("--num-processes", type=int, default=None, metavar="N")
    p.add_argument("--process-id", type=int, default=None, metavar="I")
    p.add_argument(
        "--timeout",
        type=float,
        default=60.0,
        metavar="S",
        help="seconds to wait for the other processes (default 60)",
    )


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
        "sweep": _cmd_sweep,
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
