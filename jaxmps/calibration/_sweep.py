"""`jaxmps.sweep`: one scene, a batch of Params values, one vmapped computation."""

import time
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh
from jaxtyping import Array, Float, PyTree

from .._checks import check_compatible, check_values
from .._devices import member_mesh, to_host
from .._params import Params
from .._result import Result, result_code, result_from_code
from .._scene import Scene
from .._simulate import Trajectory, _check_loop, simulate
from .._state import State
from ..scenes import Case, observe_probes
from ._fields import get_field, set_field


class SweepResult(eqx.Module):
    """Output of `sweep`.

    Attributes:
        values: the swept values, {field: (b,) array}.
        saved: observations with a leading batch axis (b, t, ...).
        result: per-member result codes (b,) as integers (0 = successful); see
            `jaxmps.Result` for the messages.
        wall_time: seconds spent in all calls (compilation included).
        first_call_time: seconds of the first chunk (compilation, on the first sweep
            of this scene and shapes, + one run).
    """

    values: dict[str, Any]
    saved: Any
    result: Any
    wall_time: float
    first_call_time: float

    def messages(self) -> list[str]:
        """Per member, "successful" or the message of the `jaxmps.Result` that
        ended its run."""
        return [
            "successful" if int(code) == 0 else Result[result_from_code(int(code))]
            for code in np.asarray(self.result)
        ]

    def failed(self) -> dict[int, str]:
        """{member index: message} of the members whose run failed."""
        return {i: m for i, m in enumerate(self.messages()) if m != "successful"}

    def save(self, path) -> None:
        """Write the sweep to one HDF5 file: /values/<field> (b, ...), /saved/<name>
        (b, saves, ...) for a dict of observations (the probes), /result (b,) codes
        and the attribute `messages`. In a multi-process run every process holds
        the whole result: call it on process 0 (`jax.process_index() == 0`)."""
        import json

        import h5py

        if not isinstance(self.saved, dict):
            raise ValueError(
                "SweepResult.save writes a dict of observations (the probes, "
                "sweep's default `observe`)."
            )
        with h5py.File(path, "w") as f:
            f.attrs["format"] = "jaxmps-sweep-result"
            f.attrs["messages"] = json.dumps(self.messages())
            for name, value in self.values.items():
                f.create_dataset(f"values/{name}", data=np.asarray(value))
            for name, value in self.saved.items():
                f.create_dataset(f"saved/{name}", data=np.asarray(value))
            f.create_dataset("result", data=np.asarray(self.result))


def _host_values(name: str, value) -> np.ndarray:
    """Swept values as a float array on the host (ValueError naming the field)."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(
            f"Values of {name!r} must be numbers, got {value!r}."
        ) from None
    if array.ndim == 0 or array.shape[0] == 0:
        raise ValueError(
            f"Values of {name!r} need a leading batch axis of at least one member, "
            f"got shape {array.shape}."
        )
    return array


def batch_params(params: Params, values: dict[str, Any]) -> tuple[Params, Params, int]:
    """Params whose listed fields carry a leading batch axis, and the vmap axes."""
    if not values:
        raise ValueError("Nothing to sweep: `values` names no Params field.")
    for name in values:
        if get_field(params, name) is None:
            raise ValueError(
                f"Params.{name} is not set in this case (None), so it has no shape "
                "to sweep; give it a value first (a scene setting or "
                "`eqx.tree_at`), then sweep it."
            )
    host = {name: _host_values(name, value) for name, value in values.items()}
    sizes = {name: len(value) for name, value in host.items()}
    if len(set(sizes.values())) != 1:
        raise ValueError(f"All swept fields need the same length, got {sizes}.")
    axes = jax.tree.map(lambda _: None, params)
    batched = params
    for name, value in host.items():
        base = get_field(params, name)
        arr = jnp.asarray(value, dtype=base.dtype)
        if arr.ndim != base.ndim + 1:
            raise ValueError(
                f"Values of {name!r} need shape (b,) + {base.shape}, got {arr.shape}."
            )
        batched = set_field(batched, name, arr)
        axes = eqx.tree_at(
            lambda p, n=name: get_field(p, n), axes, 0, is_leaf=lambda x: x is None
        )
    return batched, axes, len(next(iter(host.values())))


def checked_batch(case, values: dict[str, Any]):
    """`batch_params` of the case's Params, after checking on the host that every
    member passes the checks of a single run (ValueError naming the member)."""
    batched, axes, b = batch_params(case.params, values)
    # Every member passes the checks of a single run, on the host, before tracing.
    for i in range(b):
        member = jax.tree.map(
            lambda x, a: x if a is None else x[i],
            batched,
            axes,
            is_leaf=lambda x: x is None,
        )
        where = ", ".join(
            f"{name}={np.asarray(get_field(member, name)).tolist()}" for name in values
        )
        try:
            check_values(member)
            check_compatible(case.scene, member, case.state)
        except ValueError as e:
            raise ValueError(f"Sweep member {i} ({where}): {e}") from None
    return batched, axes, b


@eqx.filter_jit
def _batched(
    scene: Scene,
    params: Params,
    state: State,
    axes: Params,
    state_axis: int | None,
    observe: Callable[[Scene, State], PyTree],
    loop: tuple,
    times: Float[Array, " t"] | None,
) -> Trajectory:
    """The members of one device, vmapped: one compiled program per (scene,
    shapes, axes, observe, loop), which repeated sweeps reuse (the save `times`
    are traced: a run's chunks share it). `loop` is (n_steps, save_every,
    max_steps)."""
    n_steps, save_every, max_steps = loop

    def run(p, s):
        return simulate(
            scene,
            p,
            s,
            n_steps,
            save_every,
            observe,
            times=times,
            max_steps=max_steps,
            throw=False,
            batch_axis=_AXIS,
        )

    return jax.vmap(run, in_axes=(axes, state_axis), axis_name=_AXIS)(params, state)


# The batch axis: the members of a device decide together whether a step can use
# the neighbour lists carried from the previous one (`simulate(..., batch_axis=...)`).
_AXIS = "jaxmps_sweep"


def loop_arguments(case: Case, params: Params, n_steps, save_every, times, max_steps):
    """`simulate`'s loop arguments for a batch, checked (ValueError naming the one
    to change): ((n_steps, save_every, max_steps), the save times as an array of
    the state's dtype or None)."""
    if times is not None:
        times = np.asarray(times, dtype=float)
    n_steps, save_every, max_steps = _check_loop(
        params, case.state, n_steps, save_every, times, max_steps
    )
    if times is not None:
        times = jnp.asarray(times, case.state.time.dtype)
    return (n_steps, save_every, max_steps), times


# Choice: each device runs its own members as a program of its own (the program of
# a one-device sweep), dispatched to all devices at once, rather than one program
# partitioned over the devices (`shard_map`). XLA compiles a partitioned program
# differently: a dam-break sweep over 2 or 4 devices came out 5e-14 apart from the
# same sweep on one device, where the per-device programs give the same bits (a
# member's values do not depend on how many members share its program). The
# members of one device decide together whether a step reuses the neighbour lists;
# where that decision differs from the one-device sweep's (all members together),
# a step's neighbours come in another order and the values differ at round-off.
# No exchange between devices during the run: a multi-process sweep gathers the
# results once, at the end of each call.
def run_members(
    case: Case,
    params: Params,
    axes: Params,
    members: int,
    loop: tuple,
    observe: Callable[[Scene, State], PyTree],
    state: State | None = None,
    mesh: Mesh | None = None,
    chunk: int | None = None,
) -> tuple[Trajectory, float]:
    """The rollouts of `members` members (Params batched along `axes`; `state`
    batched too, or None for the case's) split over the devices of `mesh`
    (default: all), in calls of at most `chunk` members (default: all), two or
    more members per device (fewer devices if there are not enough members; in a
    multi-process run every device, padded), each share padded to an equal number
    by repeating the last member. The
    trajectories (numpy, on every process) and the seconds of the first call
    (compilation included)."""
    mesh = member_mesh(mesh)
    devices = list(mesh.devices.flat)
    state_axis = None if state is None else 0
    state = case.state if state is None else state
    state_axes = jax.tree.map(lambda _: state_axis, state)
    per_call = members if chunk is None else min(int(chunk), members)
    devices, share = device_shares(per_call, devices, jax.process_count() > 1)
    pieces, first = [], 0.0
    for lo in range(0, members, share * len(devices)):
        t0 = time.perf_counter()
        runs = {}
        for k, device in enumerate(devices):
            if device.process_index != jax.process_index():
                continue
            start = lo + k * share
            index = np.minimum(np.arange(start, start + share), members - 1)
            runs[k] = _batched(
                case.scene,
                jax.device_put(_take(params, axes, index), device),
                jax.device_put(_take(state, state_axes, index), device),
                axes,
                state_axis,
                observe,
                *loop,
            )
        pieces.append(_gathered(runs, devices))
        if lo == 0:
            first = time.perf_counter() - t0
    whole = jax.tree.map(lambda *xs: np.concatenate(xs)[:members], *pieces)
    return whole, first


def device_shares(members: int, devices: list, every: bool = False):
    """The devices a batch of `members` runs on and the members per device: two
    at least (XLA compiles a batch of one differently: its values differ at
    round-off from those of a larger batch), so fewer devices when there are not
    enough members, unless `every` (a multi-process run, where each process must
    hold a share)."""
    share = max(-(-members // len(devices)), min(2, members))
    return (devices if every else devices[: -(-members // share)]), share


def _gathered(runs: dict[int, Trajectory], devices: list) -> Trajectory:
    """The shares of every device, in device order, as numpy on every process."""
    local = [to_host(runs[k]) for k in sorted(runs)]
    if jax.process_count() == 1:
        return jax.tree.map(lambda *xs: np.concatenate(xs), *local)
    from jax.experimental import multihost_utils

    mine = jax.tree.map(lambda *xs: np.stack(xs), *local)
    every = multihost_utils.process_allgather(mine)  # (processes, shares, ...)
    owners = [d.process_index for d in devices]
    slot = {p: 0 for p in set(owners)}
    order = []
    for p in owners:
        order.append((p, slot[p]))
        slot[p] += 1
    return jax.tree.map(
        lambda x: np.concatenate([np.asarray(x)[p, i] for p, i in order]), every
    )


def _take(tree, axes, index: np.ndarray):
    """The members `index` of the batched leaves of `tree` (`axes` 0)."""
    return jax.tree.map(
        lambda x, a: x if a is None else np.asarray(x)[index],
        tree,
        axes,
        is_leaf=lambda x: x is None,
    )


def sweep(
    case: Case,
    values: dict[str, Any],
    n_steps: int | None = None,
    save_every: int | None = None,
    observe=None,
    chunk: int | None = None,
    *,
    times=None,
    max_steps: int | None = None,
    mesh: Mesh | None = None,
) -> SweepResult:
    """Run `case` once per member of a batch of Params values, vmapped, with the
    members split over devices.

    Args:
        case: a `jaxmps.scenes.Case`.
        values: {Params field name: (b,) values}; dotted names reach sub-params
            ("inflow.velocity", "motion.amplitude").
        n_steps, save_every, times, max_steps: as for `simulate`: a number of steps
            saved every `save_every`, or the save times [s] (every member saves at
            the same times, whatever steps it takes to get there).
        observe: default: the case's probes (a dict per save).
        chunk: members per vmapped call (default: the whole batch). The batch is
            split into equal chunks (the last one padded by repeating a member), so
            the program compiles once.
        mesh: a one-axis `jax.sharding.Mesh` the members are split along (default:
            every device JAX sees, over all processes of a multi-process run). A
            chunk is padded to a whole number of members per device; the results
            equal those on one device.

    Returns:
        A `SweepResult` (on every process). Members fail independently: check
        `result`, or `SweepResult.failed()` for their messages.

    Raises:
        ValueError: for values that are not numbers, empty, of unequal lengths, or
            of a member that a single run would refuse (non-finite, a negative
            density, a step beyond a stability limit...), naming the member; for
            inconsistent loop arguments; for a mesh of more than one axis.
    """
    observe = observe_probes(case.probes) if observe is None else observe
    batched, axes, b = checked_batch(case, values)
    whole = isinstance(chunk, (int, np.integer)) and not isinstance(chunk, bool)
    if chunk is not None and not (whole and chunk >= 1):
        raise ValueError(f"chunk must be a whole number >= 1, got {chunk!r}.")
    mesh = member_mesh(mesh)
    loop = loop_arguments(case, batched, n_steps, save_every, times, max_steps)
    start = time.perf_counter()
    trajectory, first_call_time = run_members(
        case, batched, axes, b, loop, observe, mesh=mesh, chunk=chunk
    )
    return SweepResult(
        values={k: jnp.asarray(v) for k, v in values.items()},
        saved=trajectory.saved,
        result=np.asarray(result_code(trajectory.result)),
        wall_time=time.perf_counter() - start,
        first_call_time=first_call_time,
    )
