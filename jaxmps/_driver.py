"""`jaxmps.run`: the host driver (chunked `simulate`, progress, HDF5, result check)."""

import dataclasses
import math
import os
import time as _time
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np

from ._result import Result
from ._simulate import frame, simulate
from .io._hdf5 import RunWriter, load_state


class _Observer(eqx.Module):
    """Observe a Frame, the step number, the result value and the probes at once."""

    probes: tuple

    def __call__(self, scene, state):
        values = {"time": state.time}
        for probe in self.probes:
            values[probe.name] = probe(scene, state)
        return frame(scene, state), state.step, state.result._value, values


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


def run(
    case: Any,
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
    dt = float(np.asarray(case.params.dt))
    if not t_end > 0:
        raise ValueError(f"t_end must be positive, got {t_end}.")
    total_steps = max(1, round(t_end / dt))
    save_every = t_end / 100 if save_every is None else float(save_every)
    if not save_every > 0:
        raise ValueError(f"save_every must be positive, got {save_every}.")
    steps_per_save = max(1, min(total_steps, round(save_every / dt)))
    out = None if out is None else Path(out)
    if restart and restart_from is None:
        if out is None:
            raise ValueError("restart=True needs `out` (the run file to continue).")
        restart_from = out
    restart_from = None if restart_from is None else Path(restart_from)

    state = case.state
    append = False
    if restart_from is not None:
        state = load_state(restart_from, case)
        append = out is not None and out.resolve() == restart_from.resolve()
    done = int(np.asarray(state.step))
    # On restart: the steps left to t_end at this dt (the restart may change dt).
    t_now = float(np.asarray(state.time))
    remaining = total_steps if restart_from is None else round((t_end - t_now) / dt)
    n_saves = math.ceil(max(0, remaining) / steps_per_save)
    chunk = _largest_divisor(n_saves, int(chunk_saves)) if n_saves else 0

    observer = _Observer(probes=tuple(case.probes))
    writer = None
    probe_rows: list[dict] = []
    if out is not None:
        writer = RunWriter(out, case, append=append)
        if append:
            # Drop frames computed after the state we continue from (a failed chunk).
            steps = (
                writer.file["frames/step"][...]
                if "step" in writer.file["frames"]
                else []
            )
            writer.truncate(int(np.sum(np.asarray(steps) <= done)))
    try:
        if not append:
            fr, step, _, values = _host(observer(case.scene, state))
            fr = jax.tree_util.tree_map(lambda x: x[None], fr)
            values = {k: np.asarray(v)[None] for k, v in values.items()}
            probe_rows.append(values)
            if writer is not None:
                writer.append_frames(fr, step=np.asarray(step)[None])
                writer.append_probes(values)
                writer.write_state(state)
        bar = None
        if progress and n_saves:
            from tqdm.auto import tqdm

            bar = tqdm(
                total=n_saves * steps_per_save,
                initial=0,
                delay=3.0,
                unit="step",
                desc=f"{case.name} (t_end={t_end:g} s)",
                leave=False,
            )
        try:
            for _ in range(n_saves // chunk if chunk else 0):
                trajectory = simulate(
                    case.scene,
                    case.params,
                    state,
                    chunk * steps_per_save,
                    steps_per_save,
                    observe=observer,
                    throw=False,
                )
                fr, steps, results, values = _host(trajectory.saved)
                failed = int(np.asarray(trajectory.result._value)) != 0
                keep = chunk
                if failed:
                    bad = np.nonzero(np.asarray(results) != 0)[0]
                    keep = int(bad[0]) + 1 if len(bad) else chunk
                    fr, steps, values = _rows((fr, steps, values), keep)
                probe_rows.append(values)
                if writer is not None:
                    writer.append_frames(fr, step=steps)
                    writer.append_probes(values)
                if failed:
                    if keep > 1:
                        # The last good state is that of the last successful save:
                        # replay those saves of the chunk (the rollout is
                        # deterministic) so that a restart continues from there.
                        state = simulate(
                            case.scene,
                            case.params,
                            state,
                            (keep - 1) * steps_per_save,
                            steps_per_save,
                            observe=observer,
                            throw=False,
                        ).state
                        if writer is not None:
                            writer.write_state(state)
                    t_fail = float(np.asarray(fr.time)[-1])
                    t_good = float(np.asarray(state.time))
                    message = Result[trajectory.result]
                    where = f" Written so far: '{out}'." if out is not None else ""
                    raise RuntimeError(
                        f"The run of '{case.name}' failed between t={t_good:.6g} s and "
                        f"t={t_fail:.6g} s (by step {int(np.asarray(steps)[-1])}): "
                        f"{message}{where}"
                    )
                state = trajectory.state
                if writer is not None:
                    writer.write_state(state)
                if bar is not None:
                    bar.update(chunk * steps_per_save)
        finally:
            if bar is not None:
                bar.close()
    finally:
        if writer is not None:
            writer.close()
    probes = {}
    if probe_rows:
        for name in probe_rows[0]:
            probes[name] = np.concatenate([np.asarray(r[name]) for r in probe_rows])
    return RunResult(
        state=state,
        probes=probes,
        path=out,
        n_steps=int(np.asarray(state.step)) - done,
        wall_time=_time.perf_counter() - started,
    )
