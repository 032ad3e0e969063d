"""`jaxmps.run`: the host driver (chunked `simulate`, progress, HDF5, result check)."""

import contextlib
import dataclasses
import math
import os
import time as _time
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, ArrayLike, Int

from ._result import Result, result_code
from ._scene import Scene
from ._simulate import Frame, frame, simulate
from ._state import State
from .io import RunWriter, load_state
from .scenes import Case


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


@dataclasses.dataclass(frozen=True)
class _Plan:
    """The saves a run makes: `n_saves` saves of `steps_per_save` steps, computed in
    chunks of `chunk` saves (one compiled program)."""

    steps_per_save: int
    n_saves: int
    chunk: int


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


def _plan(
    dt: float, t_end: float, save_every: float, t_now: float | None, chunk_saves: int
) -> _Plan:
    """Steps per save (save_every rounded to whole steps) and the saves to make: to
    `t_end` from the start, or on restart from `t_now` at this dt (a restart may
    change dt)."""
    if not t_end > 0:
        raise ValueError(f"t_end must be positive, got {t_end}.")
    if not save_every > 0:
        raise ValueError(f"save_every must be positive, got {save_every}.")
    total_steps = max(1, round(t_end / dt))
    steps_per_save = max(1, min(total_steps, round(save_every / dt)))
    remaining = total_steps if t_now is None else round((t_end - t_now) / dt)
    n_saves = math.ceil(max(0, remaining) / steps_per_save)
    chunk = _largest_divisor(n_saves, int(chunk_saves)) if n_saves else 0
    return _Plan(steps_per_save=steps_per_save, n_saves=n_saves, chunk=chunk)


def _open_writer(
    out: Path | None, case: Case, append: bool, done: int
) -> RunWriter | None:
    """The run file's writer (None without `out`); when appending, the frames
    computed after the state a restart continues from are dropped first."""
    if out is None:
        return None
    writer = RunWriter(out, case, append=append)
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
) -> None:
    if writer is None:
        return
    writer.append_frames(fr, step=steps)
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
    _write(writer, fr, np.asarray(step)[None], values, state)
    return values


def _chunk(
    case: Case,
    observer: _Observer,
    state: State,
    plan: _Plan,
    writer: RunWriter | None,
    out: Path | None,
) -> tuple[State, dict[str, np.ndarray]]:
    """Run one chunk of saves and write it; the new state and its probe rows.

    Raises:
        RuntimeError: if the chunk failed, after writing every frame up to the
            failure and, as `/state`, the state of the last successful save.
    """
    trajectory = simulate(
        case.scene,
        case.params,
        state,
        plan.chunk * plan.steps_per_save,
        plan.steps_per_save,
        observe=observer,
        throw=False,
    )
    fr, steps, results, values = _host(trajectory.saved)
    if int(np.asarray(result_code(trajectory.result))) == 0:
        _write(writer, fr, steps, values, trajectory.state)
        return trajectory.state, values
    bad = np.nonzero(np.asarray(results) != 0)[0]
    keep = int(bad[0]) + 1 if len(bad) else plan.chunk
    fr, steps, values = _rows((fr, steps, values), keep)
    _write(writer, fr, steps, values)
    good = _last_good(case, observer, state, keep - 1, plan, writer)
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
    saves: int,
    plan: _Plan,
    writer: RunWriter | None,
) -> State:
    """The state of the last successful save of a failed chunk (`saves` saves after
    `state`), replayed (the rollout is deterministic) and written as `/state`, so
    that a restart continues from there."""
    if saves < 1:
        return state
    good = simulate(
        case.scene,
        case.params,
        state,
        saves * plan.steps_per_save,
        plan.steps_per_save,
        observe=observer,
        throw=False,
    ).state
    if writer is not None:
        writer.write_state(good)
    return good


def _progress(show: bool, plan: _Plan, label: str):
    """A progress bar over the run's steps (shown after 3 s), or a null context."""
    if not (show and plan.n_saves):
        return contextlib.nullcontext(None)
    from tqdm.auto import tqdm

    return tqdm(
        total=plan.n_saves * plan.steps_per_save,
        delay=3.0,
        unit="step",
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
) -> RunResult:
    """Run a case to `t_end` on the host, in chunks of `simulate`, saving as it goes.

    The run is `n_saves` saves of `save_every` each; they are computed in chunks of an
    equal number of saves (the largest divisor of `n_saves` not above `chunk_saves`)
    so that `simulate` compiles once. Between chunks the frames and probes are appended
    to the run file and `/state` is updated. Each chunk runs with `throw=False`; its
    result is checked on the host.

    Args:
        case: a `jaxmps.scenes.Case`.
        t_end: simulated end time [s] (default `case.t_end`). On restart, the total time
            of the run, not the time to add.
        out: run file (`.h5`) to write, with an `.xdmf` sidecar; None writes nothing.
        save_every: simulated time between saves [s] (default: t_end / 100), rounded
            to a whole number of steps.
        progress: show a progress bar when the run takes more than a few seconds.
        chunk_saves: the most saves per compiled chunk.
        restart: continue from `/state` of `out` and append to it.
        restart_from: continue from `/state` of this file (appending to it if it is
            `out`; otherwise `out` is a new file starting at the restored state).

    Returns:
        A `RunResult`.

    Raises:
        RuntimeError: if the run failed (the message of its `jaxmps.Result` and the
            simulated time); what was computed is written first: every frame up to
            the failure, and in `/state` the state of the last successful save,
            which a restart continues from.
        ValueError: for inconsistent arguments or an unusable restart file.
    """
    started = _time.perf_counter()
    t_end = float(case.t_end if t_end is None else t_end)
    save_every = t_end / 100 if save_every is None else float(save_every)
    out = None if out is None else Path(out)
    restart_from, append = _restart_source(out, restart, restart_from)
    state = case.state if restart_from is None else load_state(restart_from, case)
    t_now = None if restart_from is None else float(np.asarray(state.time))
    dt = float(np.asarray(case.params.dt))
    plan = _plan(dt, t_end, save_every, t_now, chunk_saves)
    done = int(np.asarray(state.step))

    writer = _open_writer(out, case, append, done)
    try:
        label = f"{case.name} (t_end={t_end:g} s)"
        with _progress(progress, plan, label) as bar:
            state, rows = _saves(case, state, plan, writer, out, append, bar)
    finally:
        if writer is not None:
            writer.close()
    return RunResult(
        state=state,
        probes=_gather(rows),
        path=out,
        n_steps=int(np.asarray(state.step)) - done,
        wall_time=_time.perf_counter() - started,
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
) -> tuple[State, list[dict]]:
    """Make the plan's saves chunk by chunk (and the first frame, unless appending):
    the final state and the probe rows of every save."""
    observer = _Observer(probes=tuple(case.probes))
    rows = [] if append else [_first_frame(observer, case, state, writer)]
    for _ in range(plan.n_saves // plan.chunk if plan.chunk else 0):
        state, values = _chunk(case, observer, state, plan, writer, out)
        rows.append(values)
        if bar is not None:
            bar.update(plan.chunk * plan.steps_per_save)
    return state, rows
