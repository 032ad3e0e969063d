"""`jaxmps.run`: the host driver (chunked `simulate`, progress, HDF5, result check)."""

import contextlib
import dataclasses
import json
import math
import os
import signal
import threading
import time as _time
import warnings
from pathlib import Path
from typing import Any

import equinox as eqx
import h5py
import jax
import numpy as np
from jaxtyping import Array, ArrayLike, Int

from ._checks import check_compatible
from ._result import Result, result_code
from ._scene import Scene
from ._simulate import Frame, StepHistory, frame, simulate
from ._state import State
from .io import RunWriter, load_state
from .scenes import Case

# A run file's name ends in one of these; its sidecar is the same name with .xdmf.
RUN_SUFFIXES = (".h5", ".hdf5")


class _Observer(eqx.Module):
    """Observe a Frame, the step number, the result code and the probes at once."""

    probes: tuple

    def __call__(
        self, scene: Scene, state: State
    ) -> tuple[Frame, Int[Array, ""], Int[ArrayLike, ""], dict[str, Array]]:
        values = {"time": state.time}
        for probe in self.probes:
            values[probe.name] = probe(scene, state)
        return frame(scene, state), state.step, result_code(state.result), values


@dataclasses.dataclass
class RunResult:
    """What `jaxmps.run` returns.

    Attributes:
        state: the final `State`.
        probes: {"time": (m,), name: (m,)} numpy arrays of every probe saved by this
            call (on restart, only the new rows; the file holds them all).
        path: the run file written, or None if `out=None`.
        n_steps: steps taken by this call.
        wall_time: seconds spent in this call.
    """

    state: Any
    probes: dict
    path: Path | None
    n_steps: int
    wall_time: float


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by SIGINT or SIGTERM once the chunk being computed was written.

    Attributes:
        signal: the signal's number.
        path: the run file, holding every frame written and the last one's state.
        time: the simulated time of that state [s].
    """

    def __init__(self, signum: int, path: Path | None, time: float):
        self.signal, self.path, self.time = signum, path, time
        where = f"; '{path}' holds every frame to there" if path is not None else ""
        super().__init__(
            f"stopped by {signal.Signals(signum).name} at t={time:.6g} s{where}"
        )


@dataclasses.dataclass(frozen=True)
class _Plan:
    """The saves a run makes: at `times` (every `save_every` from the run's start,
    and `t_end`), computed in chunks of `chunk` saves (one compiled program), each
    save in at most `max_steps` step attempts."""

    times: np.ndarray
    chunk: int
    max_steps: int

    def chunks(self):
        """The save times of each chunk."""
        for start in range(0, len(self.times), self.chunk):
            yield self.times[start : start + self.chunk]


def _largest_divisor(n: int, limit: int) -> int:
    """Largest divisor of `n` that is at most `limit` (at least 1)."""
    for k in range(max(1, min(n, limit)), 0, -1):
        if n % k == 0:
            return k
    return 1


def _host(tree):
    return jax.tree_util.tree_map(np.asarray, tree)


def _rows(tree, stop: int):
    return jax.tree_util.tree_map(lambda x: x[:stop], tree)


def _seconds(name: str, value) -> float:
    """A positive, finite time [s] (ValueError naming `name`)."""
    try:
        value = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(
            f"{name} must be a number of seconds, got {value!r}."
        ) from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be positive and finite [s], got {value!r}.")
    return value


# State.step is an int32.
_MAX_STEPS = 2**31 - 1
# Frames a run writes at most (each holds every particle).
_MAX_SAVES = 10**6


def _plan(
    dt: float,
    t_end: float,
    save_every: float,
    t_now: float,
    chunk_saves: int,
    max_steps: int | None,
) -> _Plan:
    """The saves from `t_now` to `t_end`: at every multiple of `save_every` (a
    restart continues the same grid) and at `t_end`, each reached exactly (the
    last step before a save is shortened). `dt` is `Params.dt`, the step (fixed)
    or the largest step (adaptive): it sizes the default bound on steps per
    save."""
    t_end = _seconds("t_end", t_end)
    save_every = _seconds("save_every", save_every)
    if not int(chunk_saves) >= 1:
        raise ValueError(f"chunk_saves must be at least 1, got {chunk_saves!r}.")
    if t_end / dt > _MAX_STEPS:
        raise ValueError(
            f"t_end={t_end:g} s is {t_end / dt:.3g} steps of dt={dt:.4g} s, beyond "
            f"the {_MAX_STEPS} steps a run counts; lower `t_end` or raise `dt` "
            "(`dt_max` under adaptive steps)."
        )
    # Saves closer than a millionth of an interval to the next are merged into it
    # (t_end a float's rounding beyond a multiple of save_every); an interval
    # longer than the run is the run (one save, at t_end).
    span = t_end - t_now
    slack = 1e-6 * (min(save_every, span) if span > 0 else save_every)
    count = (t_end - t_now) / save_every
    if not count <= _MAX_SAVES:
        raise ValueError(
            f"t_end={t_end:g} s with save_every={save_every:g} s is "
            f"{count:.3g} saves, beyond the {_MAX_SAVES} a run writes; raise "
            "`save_every` (--save-every) or lower `t_end`."
        )
    first = math.floor((t_now + slack) / save_every) + 1
    last = math.ceil((t_end - slack) / save_every)
    times = [k * save_every for k in range(first, last)]
    if t_end > t_now + slack:
        times.append(t_end)
    times = np.asarray(times, dtype=float)
    chunk = _largest_divisor(len(times), int(chunk_saves)) if len(times) else 1
    if max_steps is None:
        longest = (
            float(np.max(np.diff(np.concatenate([[t_now], times]))))
            if len(times)
            else save_every
        )
        max_steps = min(20 * math.ceil(longest / dt) + 100, _MAX_STEPS)
    elif isinstance(max_steps, bool) or not (
        isinstance(max_steps, (int, np.integer)) and max_steps >= 1
    ):
        raise ValueError(
            f"max_steps_per_save must be a positive whole number, got {max_steps!r}."
        )
    return _Plan(times=times, chunk=chunk, max_steps=int(max_steps))


def check_output(
    out: str | os.PathLike,
    *,
    overwrite: bool = False,
    append: bool = False,
    name: str = "out",
) -> Path:
    """Refuse an output path that a run must not write (ValueError naming `name`):
    a suffix other than `RUN_SUFFIXES`, a directory, an existing file or sidecar
    (unless `overwrite`, or `append` to continue the file itself), a folder that
    is not one or cannot be written.

    Returns:
        The path.
    """
    out = Path(out)
    if out.suffix.lower() not in RUN_SUFFIXES:
        raise ValueError(
            f"{name} '{out}' must end in .h5 or .hdf5 (the run file; its ParaView "
            "sidecar is written next to it with .xdmf)."
        )
    if out.is_dir():
        raise ValueError(f"{name} '{out}' is a directory; name a run file in it.")
    if not append and not overwrite:
        for path in (out, out.with_suffix(".xdmf")):
            if path.exists():
                raise ValueError(
                    f"{name} '{out}': '{path}' exists. Give --overwrite "
                    "(`overwrite=True`) to replace it, --restart to continue the "
                    "run it holds, or another name."
                )
    folder = out.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise ValueError(f"{name} '{out}': '{folder}' is not a directory.")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{name} '{out}': the directory '{folder}' is not writable.")
    return out


def _staging(out: Path) -> Path:
    """The name a new run file is written under until its first frame exists."""
    return out.with_name(f".{out.name}.partial")


def _check_precision(path: Path, case) -> None:
    """Refuse to continue a run file in another float precision (its datasets
    would silently round the new steps, or the restored state lose digits)."""
    import h5py

    with h5py.File(path, "r") as f:
        stored = f["state/position"].dtype if "state/position" in f else None
    wanted = np.dtype(case.state.position.dtype)
    if stored is not None and np.dtype(stored) != wanted:
        flag = "with --x64" if np.dtype(stored).itemsize == 8 else "without --x64"
        raise ValueError(
            f"'{path}' holds a {np.dtype(stored).name} run but this one computes in "
            f"{wanted.name}; continue it {flag} (in Python: "
            f"jax.config.update('jax_enable_x64', {np.dtype(stored).itemsize == 8}) "
            "before building the case)."
        )


@contextlib.contextmanager
def _deferred_signals():
    """Record SIGINT and SIGTERM instead of stopping at once, so that the chunk
    being computed is written before the run stops; a second signal stops at
    once (KeyboardInterrupt, the file still closed properly). Only in the main
    thread, where Python delivers signals."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def record(signum, _):
        if received:
            raise KeyboardInterrupt
        received.append(signum)

    previous = {s: signal.signal(s, record) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield received
    finally:
        for s, handler in previous.items():
            signal.signal(s, signal.SIG_DFL if handler is None else handler)


def _open_writer(
    out: Path | None, case: Case, append: bool, done: int
) -> RunWriter | None:
    """The run file's writer (None without `out`): a new file under its staging
    name, moved to `out` by `_publish`; when appending, the frames computed after
    the state a restart continues from are dropped first."""
    if out is None:
        return None
    if not append:
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            return RunWriter(_staging(out), case, sidecar=False)
        except OSError as e:
            raise OSError(
                e.errno, f"Cannot create the run file '{out}': {e.strerror or e}."
            ) from e
    writer = RunWriter(out, case, append=True)
    if append:
        frames = writer.file["frames"]
        steps = frames["step"][...] if "step" in frames else []
        writer.truncate(int(np.sum(np.asarray(steps) <= done)))
    return writer


def _write(
    writer: RunWriter | None,
    fr: Frame,
    steps: np.ndarray,
    values: dict[str, np.ndarray],
    state: State | None = None,
    history: StepHistory | None = None,
) -> None:
    if writer is None:
        return
    writer.append_frames(fr, step=steps)
    if history is not None:
        writer.append_steps(history)
    writer.append_probes(values)
    if state is not None:
        writer.write_state(state)


def _first_frame(
    observer: _Observer, case: Case, state: State, writer: RunWriter | None
) -> dict[str, np.ndarray]:
    """Observe and write the initial state; its probe row."""
    fr, step, _, values = _host(observer(case.scene, state))
    fr = jax.tree_util.tree_map(lambda x: x[None], fr)
    values = {k: np.asarray(v)[None] for k, v in values.items()}
    nan = np.full(1, np.nan)
    first = StepHistory(
        accepted=np.zeros(1, np.int32),
        rejected=np.zeros(1, np.int32),
        dt_min=nan,
        dt_max=nan,
    )
    _write(writer, fr, np.asarray(step)[None], values, state, first)
    return values


def _chunk(
    case: Case,
    observer: _Observer,
    state: State,
    times: np.ndarray,
    plan: _Plan,
    writer: RunWriter | None,
    out: Path | None,
) -> tuple[State, dict[str, np.ndarray]]:
    """Run one chunk of saves (at `times`) and write it; the new state and its
    probe rows.

    Raises:
        RuntimeError: if the chunk failed, after writing every frame up to the
            failure and, as `/state`, the state of the last successful save.
    """
    trajectory = simulate(
        case.scene,
        case.params,
        state,
        times=times,
        max_steps=plan.max_steps,
        observe=observer,
        throw=False,
    )
    fr, steps, results, values = _host(trajectory.saved)
    history = _host(trajectory.steps)
    if int(np.asarray(result_code(trajectory.result))) == 0:
        _write(writer, fr, steps, values, trajectory.state, history)
        return trajectory.state, values
    bad = np.nonzero(np.asarray(results) != 0)[0]
    keep = int(bad[0]) + 1 if len(bad) else len(times)
    fr, steps, values, history = _rows((fr, steps, values, history), keep)
    _write(writer, fr, steps, values, history=history)
    good = _last_good(case, observer, state, times[: keep - 1], plan, writer)
    where = f" Written so far: '{out}'." if out is not None else ""
    raise RuntimeError(
        f"The run of '{case.name}' failed between "
        f"t={float(np.asarray(good.time)):.6g} s and "
        f"t={float(np.asarray(fr.time)[-1]):.6g} s (by step "
        f"{int(np.asarray(steps)[-1])}): {Result[trajectory.result]}{where}"
    )


def _last_good(
    case: Case,
    observer: _Observer,
    state: State,
    times: np.ndarray,
    plan: _Plan,
    writer: RunWriter | None,
) -> State:
    """The state of the last successful save of a failed chunk (the saves at
    `times` after `state`), replayed (the rollout is deterministic) and written as
    `/state`, so that a restart continues from there."""
    if len(times) < 1:
        return state
    good = simulate(
        case.scene,
        case.params,
        state,
        times=times,
        max_steps=plan.max_steps,
        observe=observer,
        throw=False,
    ).state
    if writer is not None:
        writer.write_state(good)
    return good


def _progress(show: bool, plan: _Plan, t_now: float, label: str):
    """A progress bar over the run's simulated time (shown after 3 s), or a null
    context."""
    if not (show and len(plan.times)):
        return contextlib.nullcontext(None)
    from tqdm.auto import tqdm

    return tqdm(
        total=round(float(plan.times[-1]) - t_now, 9),
        delay=3.0,
        unit="s",
        unit_scale=False,
        bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]",
        desc=label,
        leave=False,
    )


def _gather(rows: list[dict]) -> dict:
    """Probe rows of every chunk, concatenated per probe."""
    if not rows:
        return {}
    return {
        name: np.concatenate([np.asarray(r[name]) for r in rows]) for name in rows[0]
    }


def run(
    case: Case,
    t_end: float | None = None,
    out: str | os.PathLike | None = None,
    save_every: float | None = None,
    progress: bool = True,
    chunk_saves: int = 20,
    restart: bool = False,
    restart_from: str | os.PathLike | None = None,
    overwrite: bool = False,
    max_steps_per_save: int | None = None,
) -> RunResult:
    """Run a case to `t_end` on the host, in chunks of `simulate`, saving as it goes.

    The run saves at every multiple of `save_every` and at `t_end`, exactly (the
    last step before a save is shortened to land on it; a restart continues the
    same grid of times). The saves are computed in chunks of an equal number
    (the largest divisor of their number not above `chunk_saves`) so that
    `simulate` compiles once. Each save records the smallest and largest dt since
    the previous one and the steps taken again (run file `/frames/dt_min`,
    `dt_max`, `rejected`). Between chunks the frames and probes are appended to the
    run file and `/state` is updated. Each chunk runs with `throw=False`; its
    result is checked on the host.

    The run file records the t_end and save_every asked for and how the run
    ended (root attributes `t_end`, `save_every`, `status`: running, complete,
    failed or interrupted, and `status_message`; `jaxmps info` prints them).

    The run file is never lost or clobbered: the arguments, the restart file and
    the case's settings are checked before any file is touched; a new file is
    written as `.NAME.partial` next to `out` and moved to `out` (`os.replace`)
    once its first frame exists; from then on it holds every frame written and,
    in `/state`, the last one's state, whatever stops the run (a failure, an
    exception, a full disk, SIGINT or SIGTERM: the chunk being computed is
    finished and written first, and a second signal stops at once).

    Args:
        case: a `jaxmps.scenes.Case`.
        t_end: simulated end time [s] (default `case.t_end`; on restart, the one
            the file was asked for). On restart, the total time of the run, not
            the time to add; a file already at or past it is refused.
        out: run file (`.h5` or `.hdf5`) to write, with an `.xdmf` sidecar; None
            writes nothing.
        save_every: simulated time between saves [s] (default: t_end / 100; on
            restart, the file's).
        progress: show a progress bar when the run takes more than a few seconds.
        chunk_saves: the most saves per compiled chunk.
        restart: continue from `/state` of `out` and append to it.
        restart_from: continue from `/state` of this file (appending to it if it is
            `out`; otherwise `out` is a new file starting at the restored state).
        overwrite: replace an existing `out` (and its sidecar); without it an
            existing file is refused, as by `jaxmps run` without `--overwrite`.
            The old file stays until the new one has its first frame.
        max_steps_per_save: the most step attempts between two saves before the
            run ends with `Result.too_many_steps` (default: 20 times the steps of
            `Params.dt` in a save interval, plus 100).

    Returns:
        A `RunResult`.

    Raises:
        RuntimeError: if the run failed (the message of its `jaxmps.Result` and the
            simulated time); what was computed is written first: every frame up to
            the failure, and in `/state` the state of the last successful save,
            which a restart continues from.
        RunInterrupted: (a KeyboardInterrupt) on SIGINT or SIGTERM, after writing
            the chunk being computed.
        ValueError: for inconsistent arguments, an output path that must not be
            written, settings the case cannot run with, or an unusable restart
            file (a float64 file continued in float32 or the reverse included).
        OSError: if writing the run file failed (e.g. the disk is full), naming
            the file, which keeps what was written before.
    """
    started = _time.perf_counter()
    out = None if out is None else Path(out)
    restart_from, append = _restart_source(out, restart, restart_from)
    t_end, save_every = _run_times(case, t_end, save_every, restart_from)
    state = _starting_state(case, out, restart_from, append, overwrite)
    t_now = float(np.asarray(state.time))
    dt = float(np.asarray(case.params.dt))
    _check_times_against(case, restart_from, t_now, t_end, save_every)
    plan = _plan(dt, t_end, save_every, t_now, chunk_saves, max_steps_per_save)
    done = int(np.asarray(state.step))
    label = f"{case.name} (t_end={t_end:g} s)" if progress else None
    state, rows = _written(
        case, state, plan, (out, append, done, label), (t_end, save_every)
    )
    _warn_escaped(case, state)
    return RunResult(
        state=state,
        probes=_gather(rows),
        path=out,
        n_steps=int(np.asarray(state.step)) - done,
        wall_time=_time.perf_counter() - started,
    )


def _run_times(
    case: Case, t_end: float | None, save_every: float | None, restart_from
) -> tuple[float, float]:
    """The run's t_end and save_every, checked. A restart continues to the end
    its file was asked for, on its grid of saves, unless the case names another
    end than the file's (a case built anew with its own t_end)."""
    if t_end is None:
        t_end = resumed_end(case, restart_from) or case.t_end
    t_end = _seconds("t_end", t_end)
    if save_every is None:
        save_every = asked_times(restart_from).get("save_every", t_end / 100)
    return t_end, _seconds("save_every", save_every)


def _check_times_against(
    case: Case, restart_from, t_now: float, t_end: float, save_every: float
) -> None:
    """Refuse a restart already at or past `t_end` (ValueError); warn of saves
    closer than a fixed step."""
    if restart_from is not None and not t_end > t_now * (1 + 1e-9):
        raise ValueError(
            f"'{restart_from}' is already at t={t_now:.6g} s, at or past "
            f"t_end={t_end:.6g} s: give a later t_end (--t-end) to continue it."
        )
    dt = float(np.asarray(case.params.dt))
    if case.scene.time_step is None and save_every < dt * (1 - 1e-9):
        warnings.warn(
            f"save_every={save_every:g} s is shorter than the fixed dt={dt:g} s of "
            f"'{case.name}': each save ends a step shortened to land on it, so the "
            f"run steps by {save_every:g} s, not dt. Give save_every >= dt "
            "(--save-every), or a dt that fits.",
            stacklevel=3,
        )


def _written(
    case: Case,
    state: State,
    plan: _Plan,
    where: tuple[Path | None, bool, int, str | None],
    asked: tuple[float, float],
) -> tuple[State, list[dict]]:
    """Make the plan's saves into the run file (`_saves`), with a progress bar
    titled `label` (None: none), signals deferred to the end of a chunk, and a
    failed write named; the final state and the probe rows. `where`: (out,
    append, steps done, label); `asked`: (t_end, save_every), recorded in the
    file with how the run ends (`RunWriter.record_status`)."""
    out, append, done, label = where
    t_now = float(np.asarray(state.time))
    writer = None
    with _deferred_signals() as received:
        try:
            writer = _open_writer(out, case, append, done)
            if writer is not None:
                writer.record_run(*asked)
            with _progress(label is not None, plan, t_now, label or "") as bar:
                ended = _saves(case, state, plan, writer, out, append, bar, received)
            _ended(writer, "complete")
            return ended
        except RuntimeError as e:
            _ended(writer, "failed", str(e))
            raise
        except KeyboardInterrupt as e:
            _ended(writer, "interrupted", str(e) or "interrupted")
            raise
        except OSError as e:
            if writer is None or writer.path != out:
                raise
            raise _write_failure(e, out) from e
        finally:
            if writer is not None:
                writer.close()
                if out is not None and writer.path != out:
                    writer.path.unlink(missing_ok=True)


def _ended(writer: RunWriter | None, status: str, message: str = "") -> None:
    """Record how the run ended in its file, if it has one that can still be
    written (a failed write leaves the status 'running')."""
    if writer is None:
        return
    try:
        writer.record_status(status, message)
    except (OSError, ValueError, RuntimeError):
        pass


def resumed_end(case: Case, path: Path | None) -> float | None:
    """The t_end a restart from `path` continues to when none is given: the one
    the file was asked for, if `case` is built with the file's own t_end setting
    (None otherwise: the case's)."""
    asked = asked_times(path)
    built = asked.get("case_t_end")
    if "t_end" in asked and built is not None:
        if math.isclose(built, float(case.t_end)):
            return asked["t_end"]
    return None


def asked_times(path: Path | None) -> dict[str, float]:
    """The t_end and save_every a run file was asked for, and the t_end of the
    case it was built from (`case_t_end`, its /config's) ({} for none, a file
    that does not exist, or one written before they were recorded)."""
    if path is None or not Path(path).is_file():
        return {}
    try:
        with h5py.File(path, "r") as f:
            out = {
                k: float(f.attrs[k]) for k in ("t_end", "save_every") if k in f.attrs
            }
            config = f["config"][()] if "config" in f else None
    except OSError:
        return {}
    try:
        built = json.loads(config).get("t_end") if config is not None else None
        if built is not None:
            out["case_t_end"] = float(built)
    except (TypeError, ValueError, AttributeError):
        pass
    return out


def _warn_escaped(case: Case, state: State) -> None:
    """Warn when fluid particles left the domain and were taken out of the run."""
    escaped = int(np.asarray(state.escaped))
    if escaped:
        warnings.warn(
            f"{escaped} fluid particle(s) of '{case.name}' left the domain (spray, "
            "water over a wall) and were taken out of the run (`State.escaped`; "
            f"the run ends beyond `escape_limit` = {case.scene.escape_limit}).",
            stacklevel=3,
        )


def _starting_state(
    case: Case,
    out: Path | None,
    restart_from: Path | None,
    append: bool,
    overwrite: bool,
) -> State:
    """The state a run starts from (the case's, or the restart file's), after every
    check that must pass before a file is touched: the output path, the restart
    file's precision, and the settings the case cannot run with."""
    if out is not None:
        check_output(out, overwrite=overwrite, append=append)
    state = case.state
    if restart_from is not None:
        if not restart_from.exists():
            raise ValueError(f"Restart file '{restart_from}' does not exist.")
        state = load_state(restart_from, case)
        _check_precision(restart_from, case)
    check_compatible(case.scene, case.params, state)
    return state


def _write_failure(error: OSError, out: Path) -> OSError:
    """The error a failed write of the run file ends the run with."""
    return OSError(
        error.errno,
        f"Writing the run file '{out}' failed ({error.strerror or error}); it keeps "
        "every frame written before, and in /state the last one's state, to "
        "restart from.",
    )


def _restart_source(
    out: Path | None, restart: bool, restart_from: str | os.PathLike | None
) -> tuple[Path | None, bool]:
    """The run file a run continues from (None: the case's state), and whether the
    run appends to it (it is `out`)."""
    if restart and restart_from is None:
        if out is None:
            raise ValueError("restart=True needs `out` (the run file to continue).")
        restart_from = out
    restart_from = None if restart_from is None else Path(restart_from)
    append = (
        restart_from is not None
        and out is not None
        and out.resolve() == restart_from.resolve()
    )
    return restart_from, append


def _saves(
    case: Case,
    state: State,
    plan: _Plan,
    writer: RunWriter | None,
    out: Path | None,
    append: bool,
    bar: Any,
    received: list[int],
) -> tuple[State, list[dict]]:
    """Make the plan's saves chunk by chunk (and the first frame, unless appending,
    which moves a new run file into place): the final state and the probe rows of
    every save. A signal in `received` stops the run between chunks
    (`RunInterrupted`)."""
    observer = _Observer(probes=tuple(case.probes))
    rows = []
    if not append:
        rows.append(_first_frame(observer, case, state, writer))
        if writer is not None:
            writer.move_to(out)
    # Progress in the plan's (float64) times: the state's time may be float32,
    # whose rounding summed over the chunks overran the bar's total.
    before = float(np.asarray(state.time))
    for times in plan.chunks():
        if received:
            break
        state, values = _chunk(case, observer, state, times, plan, writer, out)
        rows.append(values)
        if bar is not None:
            step = round(float(times[-1]) - before, 9)
            bar.update(max(0.0, min(step, bar.total - bar.n)))
        before = float(times[-1])
    if received:
        raise RunInterrupted(received[0], out, float(np.asarray(state.time)))
    return state, rows
