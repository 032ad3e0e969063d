"""`jaxmps.sweep_run`: a sweep to `t_end` with one run file per member and an
index, computed in chunks of saves with the members split over devices (what
`jaxmps sweep` runs)."""

import dataclasses
import itertools
import json
import os
import time as _time
from pathlib import Path
from typing import Any

import jax
import numpy as np
from jax.sharding import Mesh

from ._devices import member_mesh
from ._driver import (
    RUN_SUFFIXES,
    RunInterrupted,
    _deferred_signals,
    _first_frame,
    _Observer,
    _plan,
    _progress,
    _seconds,
    _write,
)
from ._result import Result, result_from_code, result_name
from .calibration._sweep import checked_batch, loop_arguments, run_members
from .io import RunWriter
from .io._hdf5 import _jaxmps_version, _jsonable
from .scenes import Case

# The index of a sweep's folder, and its format.
INDEX_NAME = "sweep.json"
INDEX_FORMAT = "jaxmps-sweep"


@dataclasses.dataclass
class SweepRunResult:
    """What `jaxmps.sweep_run` returns.

    Attributes:
        folder: the folder holding the run files and the index.
        index: the index as written (`INDEX_NAME` in the folder).
        wall_time: seconds spent.
    """

    folder: Path
    index: dict
    wall_time: float


def grid(values: dict[str, Any]) -> dict[str, np.ndarray]:
    """Every combination of the values of each name (the first name varies
    slowest), as equal-length arrays: what `jaxmps sweep --vary` runs."""
    names = list(values)
    rows = list(itertools.product(*(np.atleast_1d(values[n]) for n in names)))
    return {n: np.asarray([r[i] for r in rows]) for i, n in enumerate(names)}


def check_folder(out: str | os.PathLike, overwrite: bool) -> Path:
    """The folder a sweep writes (ValueError naming `--out`): a new or empty
    folder, or with `overwrite` one holding a sweep's index, whose member files
    are replaced."""
    out = Path(out)
    if out.suffix in RUN_SUFFIXES:
        raise ValueError(
            f"--out '{out}' names a run file; a sweep writes a folder of them "
            "(give a folder name)."
        )
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out '{out}' exists and is not a folder.")
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise ValueError(
                f"--out '{out}' is not empty; give a new folder, or --overwrite to "
                "replace the sweep in it."
            )
        if not (out / INDEX_NAME).exists():
            raise ValueError(
                f"--out '{out}' holds files but no sweep index ({INDEX_NAME}); "
                "--overwrite replaces only a sweep's folder."
            )
    parent = out.parent if out.parent != Path("") else Path(".")
    if parent.exists() and not os.access(parent, os.W_OK):
        raise ValueError(f"--out '{out}': the folder '{parent}' cannot be written.")
    return out


def sweep_run(
    case: Case,
    values: dict[str, Any],
    t_end: float | None = None,
    out: str | os.PathLike = "sweep",
    save_every: float | None = None,
    *,
    mesh: Mesh | None = None,
    chunk_saves: int = 20,
    max_steps_per_save: int | None = None,
    overwrite: bool = False,
    progress: bool = True,
) -> SweepRunResult:
    """Run `case` once per member of `values` to `t_end`, writing one run file per
    member (`member_000.h5`, ...) and an index (`sweep.json`: the varied values,
    each member's file, result and time reached) in the folder `out`.

    The members run as one vmapped batch split over the devices of `mesh`
    (default: every device; in a multi-process run, every process computes its
    share and process 0 writes the files). Saves are at every multiple of
    `save_every` and at `t_end`, computed in chunks of up to `chunk_saves`
    saves; between chunks the files and the index are written. A member that
    fails keeps its frames up to the failure (the index names the failure); the
    others go on. A member file's `/state` is the state at the end of its last
    chunk without a failure. SIGINT or SIGTERM stop the sweep once the chunk
    being computed is written (`RunInterrupted`).

    Args:
        case: a `jaxmps.scenes.Case`.
        values: {Params field name: (b,) values}, as for `sweep` (see `grid` for
            every combination of several fields).
        t_end, save_every: as for `run` (defaults: `case.t_end`, t_end / 100).
        mesh: a one-axis `jax.sharding.Mesh` (default: all devices).
        chunk_saves: the most saves per compiled chunk.
        max_steps_per_save: as for `run`.
        overwrite: replace the sweep in an existing `out` folder.
        progress: show a progress bar.

    Returns:
        A `SweepRunResult`.

    Raises:
        ValueError: for bad values or members (named), a folder that must not be
            written, or bad times.
    """
    started = _time.perf_counter()
    out = check_folder(out, overwrite)
    t_end = _seconds("t_end", case.t_end if t_end is None else t_end)
    save_every = _seconds(
        "save_every", t_end / 100 if save_every is None else save_every
    )
    batched, axes, b = checked_batch(case, values)
    mesh = member_mesh(mesh)
    dt = float(np.max(np.asarray(batched.dt)))
    plan = _plan(dt, t_end, save_every, 0.0, chunk_saves, max_steps_per_save)
    index = _new_index(case, values, b, t_end, save_every, mesh)
    writers = (
        _open(out, case, index["members"], t_end, save_every)
        if jax.process_index() == 0
        else None
    )
    try:
        label = f"sweep of {case.name}: {b} members" if progress else None
        with (
            _deferred_signals() as received,
            _progress(label is not None, plan, 0.0, label or "") as bar,
        ):
            try:
                _chunks(
                    case,
                    (batched, axes, b),
                    plan,
                    mesh,
                    (writers, out, index),
                    bar,
                    received,
                )
            except KeyboardInterrupt as e:
                _ended(writers, out, index, "interrupted", str(e) or "interrupted")
                raise
            _ended(writers, out, index, "complete")
    finally:
        for w in writers or ():
            w.close()
    return SweepRunResult(
        folder=out, index=index, wall_time=_time.perf_counter() - started
    )


def _ended(writers, out: Path, index: dict, status: str, message: str = "") -> None:
    """Record how the sweep ended in the index and in each member's file whose
    run did not fail before (those say so already)."""
    if writers is None:
        return
    index["status"] = status if not message else f"{status}: {message}"
    _write_index(out, index)
    for writer, member in zip(writers, index["members"]):
        if not member.get("code"):
            writer.record_status(status, message)


def _new_index(case: Case, values, b: int, t_end, save_every, mesh: Mesh) -> dict:
    """The index of a sweep about to run: its settings and a file per member."""
    members = [
        {
            "file": f"member_{i:0{max(3, len(str(b - 1)))}d}.h5",
            "values": {
                name: _jsonable(np.asarray(values[name], dtype=float)[i])
                for name in values
            },
        }
        for i in range(b)
    ]
    return {
        "format": INDEX_FORMAT,
        "jaxmps_version": _jaxmps_version(),
        "scene": case.name,
        "config": _jsonable(dict(case.config)),
        "varied": list(values),
        "t_end": t_end,
        "save_every": save_every,
        "devices": int(mesh.devices.size),
        "processes": jax.process_count(),
        "members": members,
    }


def _chunks(case: Case, batch: tuple, plan, mesh, files, bar, received) -> None:
    """Write the first frame, then run and write the plan's chunks of saves (the
    index after each), until the end or every member has failed. A signal in
    `received` stops the sweep between chunks (`RunInterrupted`)."""
    batched, axes, b = batch
    writers, out, index = files
    members = index["members"]
    observer = _Observer(tuple(case.probes))
    state = None
    failed = np.zeros(b, bool)
    reached = np.zeros(b)
    for w in writers or ():
        _first_frame(observer, case, case.state, w)
    for times in plan.chunks():
        loop = loop_arguments(case, batched, None, None, times, plan.max_steps)
        trajectory, _ = run_members(
            case, batched, axes, b, loop, observer, state, mesh=mesh
        )
        state = trajectory.state
        _record(trajectory, writers, failed, reached, members)
        if writers is not None:
            _write_index(out, index)
        if bar is not None:
            bar.update(round(float(times[-1]) - bar.n, 9))
        if failed.all():
            break
        if received:
            raise RunInterrupted(received[0], out, float(times[-1]))


def _open(
    out: Path, case: Case, members: list[dict], t_end: float, save_every: float
) -> list[RunWriter]:
    """The members' run files, new. Each file's config holds its member's values
    where a varied name is a scene setting (viscosity, density, ...), so that
    `jaxmps run --restart` continues the member; the attribute `sweep_values`
    holds them all."""
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("member_*.*"):
        old.unlink()
    (out / INDEX_NAME).unlink(missing_ok=True)
    writers = []
    for m in members:
        config = dict(case.config)
        config.update({k: v for k, v in m["values"].items() if k in config})
        writer = RunWriter(out / m["file"], dataclasses.replace(case, config=config))
        writer.file.attrs["sweep_values"] = json.dumps(m["values"])
        writer.record_run(t_end, save_every)
        writers.append(writer)
    return writers


def _record(trajectory, writers, failed, reached, members) -> None:
    """Write each member's rows of a chunk (up to its first failure) and update
    `failed`, `reached` and the members' index entries."""
    fr, steps, results, values = trajectory.saved
    history = trajectory.steps
    for i, member in enumerate(members):
        if failed[i]:
            continue
        codes = np.asarray(results[i])
        bad = np.nonzero(codes != 0)[0]
        keep = int(bad[0]) + 1 if len(bad) else len(codes)
        rows = jax.tree.map(
            lambda x, i=i, k=keep: x[i][:k], (fr, steps, values, history)
        )
        if writers:
            final = None if len(bad) else jax.tree.map(lambda x: x[i], trajectory.state)
            _write(writers[i], rows[0], rows[1], rows[2], final, rows[3])
        reached[i] = float(np.asarray(rows[0].time)[-1])
        code = int(codes[bad[0]]) if len(bad) else 0
        failed[i] = code != 0
        item = result_from_code(code)
        member["result"] = result_name(item)
        member["code"] = code
        if code:
            member["message"] = Result[item]
            if writers:
                writers[i].record_status("failed", member["message"])
        member["t_reached"] = float(reached[i])
        member["steps"] = int(np.asarray(rows[1])[-1])


def _write_index(out: Path, index: dict) -> None:
    """Write the index atomically (a reader never sees half of it)."""
    staging = out / f".{INDEX_NAME}.partial"
    staging.write_text(json.dumps(index, indent=1, sort_keys=False))
    os.replace(staging, out / INDEX_NAME)


def read_index(path: str | os.PathLike) -> dict:
    """A sweep's index (`path`: the folder or its `sweep.json`), checked.

    Raises:
        ValueError: if it is missing, not JSON, or not a jaxmps sweep index.
    """
    path = Path(path)
    if path.is_dir():
        path = path / INDEX_NAME
    try:
        index = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"'{path}' does not exist.") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"'{path}' is not a jaxmps sweep index: {e}.") from None
    if not isinstance(index, dict) or index.get("format") != INDEX_FORMAT:
        raise ValueError(f"'{path}' is not a jaxmps sweep index.")
    return index
