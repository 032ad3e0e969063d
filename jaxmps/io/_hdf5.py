"""Run files: the HDF5 layout of docs/architecture.md ("Run files") and its XDMF
sidecar for ParaView."""

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

import h5py
import jax.numpy as jnp
import numpy as np

from .._result import result_code, result_from_code
from .._scene import Scene
from .._state import State

FORMAT = "jaxmps-run"
FORMAT_VERSION = 1

# How a run file's run ended (root attribute `status`): still running (or
# stopped without a word: a crash, a full disk), at its t_end, at a failure of
# the rollout, or by a signal.
RUN_STATUSES = ("running", "complete", "failed", "interrupted")

# /state fields, in State order (result is stored as its integer value).
STATE_FIELDS = (
    "time",
    "step",
    "position",
    "velocity",
    "pressure",
    "kind",
    "active",
    "result",
)
# /state fields run files of earlier versions lack (read as 0 from those).
LATER_STATE_FIELDS = ("dt", "acceleration", "escaped")
# Body sub-state fields run files of earlier versions lack (read as 0 from those).
LATER_BODY_FIELDS = {
    "grains": ("reaction", "attached", "origin"),
    "rigid": ("wall_push",),
    "elastic": ("wall_push",),
}
FRAME_FIELDS = ("time", "step", "position", "velocity", "pressure", "active")


def _jaxmps_version() -> str:
    """The installed jaxmps version (imported lazily: `jaxmps` imports this module)."""
    from .. import __version__

    return __version__


def _jsonable(value: Any) -> Any:
    """Convert numpy/jax scalars and arrays, tuples and paths into JSON values."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            return repr(value)
        return value
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (np.ndarray, np.generic)) or hasattr(value, "__jax_array__"):
        return _jsonable(np.asarray(value).tolist())
    try:
        return _jsonable(np.asarray(value).tolist())
    except Exception:  # noqa: BLE001 - last resort: keep a readable record
        return repr(value)


def config_json(config: dict) -> str:
    """`case.config` as a JSON string (numpy values converted, None kept as null)."""
    return json.dumps(_jsonable(dict(config)), sort_keys=True)


def _open_checked(path: str | os.PathLike, mode: str = "r") -> h5py.File:
    """Open a run file, raising ValueError (naming the file) if it is not one."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"Run file '{path}' does not exist.")
    try:
        f = h5py.File(path, mode)
    except OSError as e:
        raise ValueError(
            f"'{path}' cannot be read as a jaxmps run file: HDF5 cannot open it, so "
            f"it is truncated, corrupt or not HDF5 ({e})."
        ) from None
    try:
        fmt = f.attrs.get("format")
        if fmt is None:
            raise ValueError(
                f"'{path}' is not a jaxmps run file: the root attribute 'format' is "
                f"missing (expected format='{FORMAT}')."
            )
        if isinstance(fmt, bytes):
            fmt = fmt.decode()
        if str(fmt) != FORMAT:
            raise ValueError(
                f"'{path}' is not a jaxmps run file: format={fmt!r}, expected "
                f"'{FORMAT}'."
            )
        version = f.attrs.get("format_version")
        if version is None or int(version) > FORMAT_VERSION:
            raise ValueError(
                f"'{path}' has format_version="
                f"{'none' if version is None else _decode(version)}; this jaxmps reads "
                f"format_version <= {FORMAT_VERSION}."
            )
        for group in ("config", "particles", "frames", "probes"):
            if group not in f:
                raise ValueError(
                    f"'{path}' is a damaged run file: '/{group}' is missing."
                )
    except Exception:
        f.close()
        raise
    return f


def _module_fields(module: Any) -> dict:
    """The array fields of an equinox Module, by name."""
    return {f.name: getattr(module, f.name) for f in dataclasses.fields(module)}


def _append(dataset: h5py.Dataset, values: np.ndarray) -> None:
    """Append `values` along axis 0 of a resizable dataset."""
    values = np.asarray(values, dtype=dataset.dtype)
    start = dataset.shape[0]
    dataset.resize(start + values.shape[0], axis=0)
    dataset[start:] = values


def _resizable(group: h5py.Group, name: str, sample: np.ndarray) -> h5py.Dataset:
    """A dataset of 0 rows shaped like one row of `sample`, resizable along axis 0."""
    sample = np.asarray(sample)
    row = sample.shape[1:]
    row_bytes = max(1, int(np.prod(row, dtype=np.int64)) * sample.dtype.itemsize)
    chunk_rows = max(1, min(64, (1 << 20) // row_bytes))
    return group.create_dataset(
        name,
        shape=(0, *row),
        maxshape=(None, *row),
        dtype=sample.dtype,
        chunks=(chunk_rows, *row),
    )


class RunWriter:
    """Writes a run file incrementally: frames and probes are appended between
    chunks of a run, the state is overwritten; the XDMF sidecar is kept in step.

    Args:
        path: the run file (`.h5`); the sidecar is the same name with `.xdmf`.
        case: the `jaxmps.scenes.Case` being run (its config, particle kinds, dt).
        append: open an existing run file and append to it (restart) instead of
            creating a new one.
        sidecar: keep the XDMF sidecar in step (off while the file is written
            under a temporary name; `move_to` switches it on).

    Example:
        ```python
        with RunWriter("run.h5", case) as w:
            w.append_frames(trajectory.saved)
            w.write_state(trajectory.state)
        ```
    """

    def __init__(
        self,
        path: str | os.PathLike,
        case: Any,
        append: bool = False,
        *,
        sidecar: bool = True,
    ):
        self.path = Path(path)
        self.xdmf_path = self.path.with_suffix(".xdmf")
        self.sidecar = sidecar
        self.dt = float(np.asarray(case.params.dt))
        self.body_fields = tuple(model.name for model in case.scene.body_models)
        if append:
            self.file = _open_checked(self.path, "r+")
            n = self.file["particles/kind"].shape[0]
            if n != case.state.position.shape[0]:
                self.file.close()
                raise ValueError(
                    f"'{self.path}' holds {n} particles but the case has "
                    f"{case.state.position.shape[0]}: it is not a run of this case."
                )
            # The settings now in force (a restart may change them) are the ones a
            # later restart continues with; those they replace are kept, with
            # the time from which they no longer held (`earlier_configs`).
            self.file.attrs["dt"] = self.dt
            old, new = _decode(self.file["config"][()]), config_json(case.config)
            if old != new:
                state = self.file.get("state")
                since = 0.0 if state is None else float(state["time"][()])
                earlier = json.loads(self.file.attrs.get("earlier_configs", "[]"))
                earlier.append({"until_time": since, "config": json.loads(old)})
                self.file.attrs["earlier_configs"] = json.dumps(earlier)
            del self.file["config"]
            self.file.create_dataset("config", data=new)
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.file = h5py.File(self.path, "w")
        f = self.file
        position = np.asarray(case.state.position)
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["jaxmps_version"] = _jaxmps_version()
        f.attrs["scene"] = str(case.name)
        f.attrs["dim"] = int(position.shape[1])
        f.attrs["spacing"] = float(case.scene.spacing)
        f.attrs["dt"] = self.dt
        f.create_dataset("config", data=config_json(case.config))
        particles = f.create_group("particles")
        n = position.shape[0]
        particles.create_dataset(
            "kind", data=np.asarray(case.state.kind).astype(np.int8)
        )
        particles.create_dataset("body", data=_owner(case.scene, case.state, n))
        f.create_group("frames")
        f.create_group("probes")
        f.flush()

    # -- context manager -----------------------------------------------------------
    def __enter__(self) -> "RunWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- appending -----------------------------------------------------------------
    def append_frames(self, frame_batch: Any, step: Any = None) -> None:
        """Append frames stacked along axis 0 (a `jaxmps.Frame` from `simulate`).

        Args:
            frame_batch: a `Frame` (or any object with `time`, `position`, `velocity`,
                `pressure`, `active`) whose arrays have a leading save axis.
            step: the step number of each frame; default: `round(time / dt)`, or
                `frame_batch.step` if it has one.
        """
        time = np.atleast_1d(np.asarray(frame_batch.time))
        if step is None:
            step = getattr(frame_batch, "step", None)
        if step is None:
            step = np.rint(time / self.dt)
        rows = {
            "time": time,
            "step": np.atleast_1d(np.asarray(step)).astype(np.int64),
            "position": np.asarray(frame_batch.position),
            "velocity": np.asarray(frame_batch.velocity),
            "pressure": np.asarray(frame_batch.pressure),
            "active": np.asarray(frame_batch.active).astype(bool),
        }
        single = rows["position"].ndim == 2  # a single frame
        if single:
            rows = {
                k: (v if k in ("time", "step") else v[None]) for k, v in rows.items()
            }
        frames = self.file["frames"]
        for name in FRAME_FIELDS:
            if name not in frames:
                _resizable(frames, name, rows[name])
            _append(frames[name], rows[name])
        bodies = getattr(frame_batch, "bodies", None)
        if bodies:
            group = self.file.require_group("bodies")
            for name, values in bodies.items():
                values = np.asarray(values)
                if single:
                    values = values[None]
                if name not in group:
                    _resizable(group, name, values)
                _append(group[name], values)
        self.file.flush()
        self.write_xdmf()

    def append_steps(self, history: Any) -> None:
        """Append the steps behind each frame (a `jaxmps.StepHistory` with one
        entry per frame) as /frames/dt_min, dt_max (nan for the first frame) and
        rejected."""
        frames = self.file["frames"]
        for name in ("dt_min", "dt_max", "rejected"):
            values = np.atleast_1d(np.asarray(getattr(history, name)))
            if name not in frames:
                _resizable(frames, name, values)
            _append(frames[name], values)
        self.file.flush()

    def append_probes(self, dict_batch: dict) -> None:
        """Append probe values: a dict {"time": (m,), name: (m, ...)}."""
        probes = self.file["probes"]
        for name, values in dict_batch.items():
            values = np.asarray(values)
            if values.ndim == 0:
                values = values[None]
            if name not in probes:
                _resizable(probes, name, values)
            _append(probes[name], values)
        self.file.flush()

    def write_state(self, state: Any) -> None:
        """Overwrite /state with `state` (a full `jaxmps.State`), for restarts."""
        if "state" in self.file:
            del self.file["state"]
        group = self.file.create_group("state")
        for name in STATE_FIELDS + LATER_STATE_FIELDS:
            value = getattr(state, name)
            if name == "result":
                value = int(np.asarray(result_code(value)))
            group.create_dataset(name, data=np.asarray(value))
        for model in self.body_fields:
            sub = group.create_group(model)
            for name, value in _module_fields(getattr(state, model)).items():
                sub.create_dataset(name, data=np.asarray(value))
        self.file.flush()

    def record_run(self, t_end: float, save_every: float) -> None:
        """Record the end time and save interval the run is asked for (a restart
        without them continues to the same end on the same grid of saves), and
        mark it running until `record_status` says how it ended."""
        self.file.attrs["t_end"] = float(t_end)
        self.file.attrs["save_every"] = float(save_every)
        self.record_status("running")

    def record_status(self, status: str, message: str = "") -> None:
        """Record how the run ended: one of `RUN_STATUSES`, with a message (the
        failure's, or where the run was stopped)."""
        if status not in RUN_STATUSES:
            raise ValueError(f"status {status!r} is not one of {RUN_STATUSES}.")
        self.file.attrs["status"] = status
        self.file.attrs["status_message"] = message
        self.file.flush()

    def truncate(self, n_frames: int) -> None:
        """Keep only the first `n_frames` frames and probe rows (drop frames computed
        after the state a restart continues from)."""
        for group in ("frames", "probes", "bodies"):
            if group not in self.file:
                continue
            for dataset in self.file[group].values():
                if dataset.shape[0] > n_frames:
                    dataset.resize(n_frames, axis=0)
        self.file.flush()
        self.write_xdmf()

    def write_xdmf(self) -> None:
        """(Re)write the XDMF sidecar describing every frame in the file (nothing
        while `sidecar` is off)."""
        if self.sidecar:
            write_xdmf(self.file, self.xdmf_path, self.path.name)

    def move_to(self, path: str | os.PathLike) -> None:
        """Move the open run file to `path` (`os.replace`: one step within a file
        system, replacing any file there) and keep writing it there, with its
        sidecar."""
        path = Path(path)
        self.file.flush()
        os.replace(self.path, path)
        self.path, self.xdmf_path, self.sidecar = path, path.with_suffix(".xdmf"), True
        self.write_xdmf()

    def close(self) -> None:
        """Flush and close the file (idempotent)."""
        if self.file.id.valid:
            self.file.close()


def _owner(scene: Scene, state: State, n: int) -> np.ndarray:
    """/particles/body: the body each particle belongs to over all the Scene's body
    models, -1 for none."""
    body = np.full(n, -1, np.int32)
    for model in scene.body_models:
        owner = np.asarray(model.owner(state))
        body = np.where(owner >= 0, owner, body).astype(np.int32)
    return body


def _data_item(h5name: str, dataset: str, shape: tuple, dtype: np.dtype) -> str:
    dtype = np.dtype(dtype)
    kind = {"f": "Float", "i": "Int", "u": "UInt", "b": "UChar"}[dtype.kind]
    if dtype.itemsize == 1 and kind in ("Int", "UInt"):
        kind = "Char" if kind == "Int" else "UChar"
    dims = " ".join(str(s) for s in shape)
    return (
        f'<DataItem Dimensions="{dims}" NumberType="{kind}" '
        f'Precision="{dtype.itemsize}" Format="HDF">'
        f"{escape(h5name)}:{dataset}</DataItem>"
    )


def _hyperslab(h5name: str, dataset: str, shape: tuple, dtype, index: int) -> str:
    """XML for row `index` of a (t, ...) dataset."""
    rank = len(shape)
    start = [index] + [0] * (rank - 1)
    stride = [1] * rank
    count = [1] + list(shape[1:])
    row = " ".join(str(s) for s in shape[1:])
    selection = " ".join(str(v) for v in start + stride + count)
    return (
        f'<DataItem ItemType="HyperSlab" Dimensions="{row}" Type="HyperSlab">'
        f'<DataItem Dimensions="3 {rank}" Format="XML">{selection}</DataItem>'
        f"{_data_item(h5name, dataset, shape, dtype)}</DataItem>"
    )


def write_xdmf(f: h5py.File, xdmf_path: str | os.PathLike, h5name: str) -> None:
    """Write an XDMF 3 temporal collection of Polyvertex grids, one per frame, whose
    geometry and Pressure/Velocity/Kind attributes are hyperslabs of the HDF5 file.

    Args:
        f: the open run file.
        xdmf_path: where to write the sidecar.
        h5name: the run file's name relative to the sidecar.
    """
    frames = f["frames"]
    grids = []
    if "position" in frames and frames["position"].shape[0] > 0:
        pos = frames["position"]
        t, n, d = pos.shape
        times = frames["time"][...]
        geometry = "XYZ" if d == 3 else "XY"
        kind = f["particles/kind"]
        pressure, velocity = frames["pressure"], frames["velocity"]

        def slab(name: str, ds: h5py.Dataset, i: int) -> str:
            return _hyperslab(h5name, f"/frames/{name}", ds.shape, ds.dtype, i)

        for i in range(t):
            grids.append(
                f'<Grid Name="frame_{i}" GridType="Uniform">'
                f'<Time Value="{float(times[i])!r}"/>'
                f'<Topology TopologyType="Polyvertex" NumberOfElements="{n}" '
                f'NodesPerElement="1"/>'
                f'<Geometry GeometryType="{geometry}">'
                f"{slab('position', pos, i)}"
                f"</Geometry>"
                f'<Attribute Name="Pressure" AttributeType="Scalar" Center="Node">'
                f"{slab('pressure', pressure, i)}"
                f"</Attribute>"
                f'<Attribute Name="Velocity" AttributeType="Vector" Center="Node">'
                f"{slab('velocity', velocity, i)}"
                f"</Attribute>"
                f'<Attribute Name="Kind" AttributeType="Scalar" Center="Node">'
                f"{_data_item(h5name, '/particles/kind', kind.shape, kind.dtype)}"
                f"</Attribute>"
                f"</Grid>"
            )
    name = quoteattr(str(f.attrs.get("scene", "run")))
    text = (
        '<?xml version="1.0" ?>\n'
        '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
        '<Xdmf Version="3.0">\n<Domain>\n'
        f'<Grid Name={name} GridType="Collection" CollectionType="Temporal">\n'
        + "\n".join(grids)
        + "\n</Grid>\n</Domain>\n</Xdmf>\n"
    )
    tmp = Path(str(xdmf_path) + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, xdmf_path)


@dataclasses.dataclass
class RunData:
    """Everything in a run file, as numpy arrays.

    Attributes:
        path: the file read.
        attrs: root attributes (format, format_version, jaxmps_version, scene, dim,
            spacing, dt; in files of `jaxmps.run` and `jaxmps.sweep_run` also
            t_end and save_every, as asked for, and status, one of
            `RUN_STATUSES`, with status_message).
        config: the scene overrides the run was built with.
        particles: {"kind": (n,) int8, "body": (n,) int32}.
        frames: {"time", "step", "position", "velocity", "pressure", "active"},
            and in runs of `jaxmps.run` the steps behind each frame: "dt_min",
            "dt_max" (nan for the first frame) and "rejected".
        probes: {"time": (m,), name: (m, ...)}.
        state: the last full state's fields ({} if none was written).
        bodies: rigid-body fields per frame, {name: (t, b, ...)} ({} if none).
    """

    path: Path
    attrs: dict
    config: dict
    particles: dict
    frames: dict
    probes: dict
    state: dict
    bodies: dict = dataclasses.field(default_factory=dict)


def _decode(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_run(path: str | os.PathLike) -> RunData:
    """Read a whole run file.

    Raises:
        FileNotFoundError: if `path` does not exist.
        ValueError: if it is not a jaxmps run file (not HDF5, wrong or missing
            `format` attribute, missing groups), naming the file.
    """
    with _open_checked(path) as f:
        attrs = {k: _decode(v) for k, v in f.attrs.items()}
        try:
            config = json.loads(_decode(f["config"][()]))
        except (TypeError, ValueError) as e:
            raise ValueError(f"'{path}': /config is not valid JSON ({e}).") from None
        particles = {k: v[...] for k, v in f["particles"].items()}
        frames = {k: v[...] for k, v in f["frames"].items()}
        probes = {k: v[...] for k, v in f["probes"].items()}
        state = {}
        if "state" in f:
            state = {
                k: v[()] for k, v in f["state"].items() if isinstance(v, h5py.Dataset)
            }
        bodies = {k: v[...] for k, v in f["bodies"].items()} if "bodies" in f else {}
    return RunData(Path(path), attrs, config, particles, frames, probes, state, bodies)


def load_state(path: str | os.PathLike, case: Any):
    """The last full State of a run file, cast to the dtypes of `case.state`.

    Args:
        path: a run file with a /state group.
        case: the case the run was made from (gives dtypes and checks shapes).

    Returns:
        A `jaxmps.State` ready to be passed to `simulate` with `case.scene`.

    Raises:
        ValueError: if the file is not a run file, has no /state, or its shapes do not
            match the case.
    """
    with _open_checked(path) as f:
        if "state" not in f:
            raise ValueError(f"'{path}' has no /state group: nothing to restart from.")
        group = f["state"]
        missing = [k for k in STATE_FIELDS if k not in group]
        if missing:
            raise ValueError(f"'{path}': /state lacks {missing}.")
        values = {k: group[k][()] for k in STATE_FIELDS}
        values.update({k: group[k][()] for k in LATER_STATE_FIELDS if k in group})
        sub_values = {
            model: {k: v[()] for k, v in group[model].items()}
            for model in case.scene.body_fields
            if model in group
        }

    def cast(where: str, value, like):
        value = np.asarray(value)
        if value.shape != like.shape:
            raise ValueError(
                f"'{path}': {where} has shape {value.shape} but the case expects "
                f"{tuple(like.shape)}: it is not a run of this case (a restart "
                "keeps the settings that place the particles: spacing and the "
                "geometry; change them in a new run)."
            )
        return jnp.asarray(value, dtype=like.dtype)

    fields = {
        name: cast(f"/state/{name}", values[name], getattr(case.state, name))
        for name in STATE_FIELDS[:-1]
    }
    for name in LATER_STATE_FIELDS:
        like = getattr(case.state, name)
        fields[name] = cast(f"/state/{name}", values.get(name, 0.0), like)
    for model in case.scene.body_fields:
        like = getattr(case.state, model)
        stored = sub_values.get(model)
        if (like is None) != (stored is None):
            raise ValueError(
                f"'{path}': the run {'has' if stored else 'has no'} {model} bodies "
                f"but the case {'has' if like is not None else 'has none'}: it is "
                "not a run of this case."
            )
        if like is None:
            continue
        parts = {}
        for name, part in _module_fields(like).items():
            if name not in stored and name in LATER_BODY_FIELDS.get(model, ()):
                stored[name] = np.zeros(part.shape)
            if name not in stored:
                raise ValueError(f"'{path}': /state/{model} lacks '{name}'.")
            parts[name] = cast(f"/state/{model}/{name}", stored[name], part)
        fields[model] = type(like)(**parts)
    return State(**fields, result=result_from_code(int(values["result"])))


def write_run(
    path: str | os.PathLike,
    case: Any,
    frames: Any,
    probes: dict | None = None,
    final_state: Any = None,
    step: Any = None,
) -> Path:
    """Write a complete run file in one go (see `RunWriter` for incremental writing).

    Args:
        path: the `.h5` file to create (overwritten); `.xdmf` is written next to it.
        case: the `jaxmps.scenes.Case` that was run.
        frames: stacked frames (`Trajectory.saved` with the default `frame` observe).
        probes: optional {"time": (m,), name: (m,)} probe values.
        final_state: optional final `State`, stored under /state.
        step: optional step numbers of the frames.

    Returns:
        The path written.
    """
    with RunWriter(path, case) as w:
        if frames is not None:
            w.append_frames(frames, step=step)
        if probes:
            w.append_probes(probes)
        if final_state is not None:
            w.write_state(final_state)
    return Path(path)
