"""`jaxmps.sweep`: one scene, a batch of Params values, one vmapped computation."""

import time
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Int, PyTree

from .._checks import check_compatible, check_values
from .._params import Params
from .._result import Result, result_code, result_from_code
from .._scene import Scene
from .._simulate import simulate
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
        get_field(params, name)
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
    n_steps: int,
    save_every: int | None,
    observe: Callable[[Scene, State], PyTree],
    axes: Params,
) -> tuple[PyTree, Int[Array, " b"]]:
    """One compiled program per (scene, shapes, n_steps, save_every, observe, axes):
    repeated sweeps reuse it."""

    def run(p):
        tr = simulate(
            scene,
            p,
            state,
            n_steps,
            save_every,
            observe,
            throw=False,
            batch_axis=_AXIS,
        )
        return tr.saved, result_code(tr.result)

    return jax.vmap(run, in_axes=(axes,), axis_name=_AXIS)(params)


# The batch axis: the members decide together whether a step can use the neighbour
# lists carried from the previous one (`simulate(..., batch_axis=...)`).
_AXIS = "jaxmps_sweep"


def sweep(
    case: Case,
    values: dict[str, Any],
    n_steps: int,
    save_every: int | None = None,
    observe=None,
    chunk: int | None = None,
) -> SweepResult:
    """Run `case` once per member of a batch of Params values, vmapped.

    Args:
        case: a `jaxmps.scenes.Case`.
        values: {Params field name: (b,) values}; dotted names reach sub-params
            ("inflow.velocity", "motion.amplitude").
        n_steps, save_every: as for `simulate`.
        observe: default: the case's probes (a dict per save).
        chunk: members per vmapped call (default: the whole batch). The batch is
            split into equal chunks (the last one padded by repeating a member), so
            the program compiles once.

    Returns:
        A `SweepResult`. Members fail independently: check `result`, or
        `SweepResult.failed()` for their messages.

    Raises:
        ValueError: for values that are not numbers, empty, of unequal lengths, or
            of a member that a single run would refuse (non-finite, a negative
            density, a step beyond a stability limit...), naming the member.
    """
    observe = observe_probes(case.probes) if observe is None else observe
    batched, axes, b = checked_batch(case, values)
    whole = isinstance(chunk, (int, np.integer)) and not isinstance(chunk, bool)
    if chunk is not None and not (whole and chunk >= 1):
        raise ValueError(f"chunk must be a whole number >= 1, got {chunk!r}.")
    chunk = b if chunk is None else min(int(chunk), b)
    n_chunks = -(-b // chunk)

    def batched_run(chunk_params):
        return _batched(
            case.scene, chunk_params, case.state, n_steps, save_every, observe, axes
        )

    def take(lo):
        def leaf(x, a):
            if a is None:
                return x
            idx = np.minimum(np.arange(lo, lo + chunk), b - 1)
            return x[idx]

        return jax.tree.map(leaf, batched, axes, is_leaf=lambda x: x is None)

    start = time.perf_counter()
    outputs, first_call_time = [], 0.0
    for c in range(n_chunks):
        t0 = time.perf_counter()
        out = jax.block_until_ready(batched_run(take(c * chunk)))
        if c == 0:
            first_call_time = time.perf_counter() - t0
        outputs.append(out)
    saved = jax.tree.map(lambda *xs: jnp.concatenate(xs)[:b], *[o[0] for o in outputs])
    result = jnp.concatenate([o[1] for o in outputs])[:b]
    return SweepResult(
        values={k: jnp.asarray(v) for k, v in values.items()},
        saved=saved,
        result=result,
        wall_time=time.perf_counter() - start,
        first_call_time=first_call_time,
    )
