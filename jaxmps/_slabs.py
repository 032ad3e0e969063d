"""One run split over devices by space: the domain cut into slabs across x, each
device stepping the particles of its slab together with a halo of copies of its
neighbours' particles, exchanged once per step (`jax.shard_map`).

Why a halo and not XLA's partitioning (`shard_particles`): the neighbour search
of a particle-split program gathers every position on every device, so the split
buys memory, not speed (benchmarks/results/sharded_run_cpu.md). Here a device
receives only the particles within `halo` of its two cuts.

The step is the one-device step, run on a slab's particles and its halo, whose
results are kept for the slab's own particles only. The halo is wide enough for
those to be exact: an explicit step reads neighbours of neighbours (the
viscosity and collision at r^k, the number density at r*, the pressure
gradient, the stabilisation), so each of its stages widens the dependence by
r_e, and the default halo is r_e per stage plus 2 l0 for the motion within the
step. Semi-implicit steps solve one linear system over the whole domain, which
a halo exchanged once per step cannot give (it would need an exchange inside
every iteration of the solve); they are refused, and `shard_particles` splits
them instead.

After each step the particles that crossed a cut move to the neighbouring slab
(they lay in its halo, so a step cannot carry one further). At the start and at
every save the host cuts the slabs anew into equal counts of particles (at least
a halo apart), so a flow that gathers in one part of the domain (a dam break's
surge) spreads over the devices again; the slots per slab and per halo grow
there when the new layout needs more (a new compilation).
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._devices import member_mesh, to_host
from ._params import Params
from ._result import (
    Result,
    result_code,
    result_from_code,
    result_name,
    traced_result,
    update_result,
)
from ._scene import Scene
from ._simulate import Frame, frame
from ._state import State
from ._step import _step, time_step, without_neighbour_lists
from .fluid import Explicit

# The name of the mesh axis the slabs are laid along.
SLABS = "slabs"
# The per-particle fields of a fluid-and-walls State, which travel between slabs.
_FIELDS = ("position", "velocity", "pressure", "kind", "active")


class SlabRunError(RuntimeError):
    """A split run that failed (`simulate_slabs(throw=True)`); `run` holds what it
    computed up to the failure."""

    def __init__(self, message: str, run: "SlabRun"):
        super().__init__(message)
        self.run = run


class SlabRun(eqx.Module):
    """Output of `simulate_slabs` (host arrays, particles in the input's slot
    order).

    Attributes:
        state: the final state.
        saved: a `Frame` per save, stacked along a leading time axis.
        result: the first failure (lowest device first within a step), or
            `Result.successful`.
        cuts: the slabs' bounds along x [m] in the last save interval, shape
            (devices + 1,) (the outer two infinite).
        halo: the halo's width [m].
        slots: particle slots per slab (the last interval's).
        halo_slots: slots per halo side (and for the particles crossing a cut).
        peak_owned: the most particles each slab held, shape (devices,).
        peak_halo: the most particles each slab sent to one neighbour's halo,
            shape (devices,).
    """

    state: State
    saved: Frame
    result: Result
    cuts: np.ndarray
    halo: float
    slots: int
    halo_slots: int
    peak_owned: np.ndarray
    peak_halo: np.ndarray


def slab_halo(scene: Scene) -> float:
    """The default halo width [m]: r_e per stage of the step that reads its
    neighbours (viscosity, number density, pressure gradient, and the collision
    guard and dynamic stabilisation where the scene has them), plus 2 l0."""
    stages = 3 + (scene.collision is not None) + (scene.stabiliser is not None)
    return stages * scene.r_e + 2 * scene.spacing


def simulate_slabs(
    scene: Scene,
    params: Params,
    state: State,
    n_steps: int,
    save_every: int | None = None,
    *,
    devices: int | None = None,
    mesh: Mesh | None = None,
    halo: float | None = None,
    slack: float = 1.5,
    throw: bool = True,
) -> SlabRun:
    """Run `n_steps` steps of an explicit scene split over devices by slabs across
    x, saving every `save_every` steps (default: once, at the end).

    Each device holds one slab's particles and, every step, copies of the
    particles within `halo` of its cuts from its two neighbours (one
    `ppermute` each way), then moves the particles that crossed a cut to the
    neighbour (one more each way). The particles of a slab take the same step as
    in a one-device run; they differ from it by round-off only (the sums over
    neighbours run in another order). At every save the slabs are cut anew into
    equal counts. Adaptive steps take the smallest dt over the slabs; a failed
    step is not taken and not retried: the run stops with the last good state.

    Args:
        scene, params, state: an explicit scene (`solver="explicit"`) of fluid and
            fixed walls (no bodies, inflow, outflow or moving walls).
        n_steps: steps to take; a multiple of `save_every`.
        save_every: steps between saves, and between new cuts (default: n_steps).
        devices, mesh: the devices (default: all of `jax.devices()`), or a
            one-axis mesh of them; the slabs follow the mesh's order.
        halo: the halo's width [m] (default `slab_halo(scene)`); a narrower
            one gives wrong values near the cuts.
        slack: slots per slab and per halo as a multiple of the largest counts
            at a cut (the flow gathers between saves; more sets
            `Result.slab_overflow`). More slack costs work on every device.
        throw: raise `SlabRunError` (holding the run) if the run failed.

    Returns:
        A `SlabRun` (host arrays).

    Raises:
        ValueError: for a scene this split cannot run, more devices than exist,
            a domain too short for as many slabs a halo wide, or bad counts
            (naming the setting).
    """
    _check(scene, state, n_steps, save_every, halo, slack)
    save_every = n_steps if save_every is None else int(save_every)
    mesh = member_mesh(mesh, devices)
    mesh = Mesh(mesh.devices.reshape(-1), (SLABS,))
    count = int(mesh.devices.size)
    if any(d.process_index != jax.process_index() for d in mesh.devices.flat):
        raise ValueError(
            "simulate_slabs runs on the devices of one process; this mesh holds "
            "other processes' devices. Pass devices=jax.local_device_count() (or a "
            "mesh of jax.local_devices())."
        )
    halo = slab_halo(scene) if halo is None else float(halo)
    start = without_neighbour_lists(state)
    state, frames, layout = start, [], None
    peaks = np.zeros((count, 2), dtype=int)
    for _ in range(n_steps // save_every):
        if state.result == Result.successful:
            layout = _layout(state, count, halo, slack, layout)
            final, scalars, reached = _program(
                scene,
                params,
                mesh,
                layout.shape(halo),
                save_every,
                *_place(layout, mesh, state),
            )
            state = _gathered(state, layout, to_host(final), to_host(scalars))
            peaks = np.maximum(peaks, np.asarray(to_host(reached)).reshape(count, 2))
        frames.append(frame(scene, state))
    # Stacked by tree operations (a Frame's annotations are those of one save).
    saved = jax.tree.map(lambda *xs: jnp.stack(xs), *frames)
    run = SlabRun(
        state=state,
        saved=saved,
        result=state.result,
        cuts=layout.cuts,
        halo=halo,
        slots=layout.slots,
        halo_slots=layout.halo_slots,
        peak_owned=peaks[:, 0],
        peak_halo=peaks[:, 1],
    )
    if throw and state.result != Result.successful:
        raise SlabRunError(f"{result_name(state.result)}: {Result[state.result]}", run)
    return run


def _check(scene, state, n_steps, save_every, halo, slack) -> None:
    """Refuse what a split by slabs cannot run, naming the setting."""
    if not isinstance(scene.solver, Explicit):
        raise ValueError(
            "simulate_slabs runs explicit scenes only (scene setting "
            "solver='explicit'): a semi-implicit step solves one pressure system "
            "over the whole domain. Split a semi-implicit run with "
            "jaxmps.shard_particles instead."
        )
    parts = [name for name in Scene.body_fields if getattr(scene, name) is not None]
    parts += [n for n in ("inflow", "outflow", "motion") if getattr(scene, n)]
    if parts:
        raise ValueError(
            f"simulate_slabs runs fluid and fixed walls only; this scene has "
            f"{', '.join(parts)}. Run it with jaxmps.simulate (or split it with "
            "jaxmps.shard_particles)."
        )
    for name, value in (("n_steps", n_steps), ("save_every", save_every)):
        if value is None and name == "save_every":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(f"{name} must be a whole number, got {value!r}.")
        if value < 1:
            raise ValueError(f"{name} must be at least 1, got {value}.")
    if save_every is not None and n_steps % save_every:
        raise ValueError(
            f"n_steps={n_steps} is not a multiple of save_every={save_every}."
        )
    if halo is not None and not (math.isfinite(halo) and halo > 0):
        raise ValueError(f"halo must be a positive width [m], got {halo!r}.")
    if not (math.isfinite(slack) and slack >= 1):
        raise ValueError(f"slack must be at least 1, got {slack!r}.")
    if state.rigid is not None or state.elastic is not None or state.grains is not None:
        raise ValueError("simulate_slabs: the state has bodies the scene does not.")


class _Layout(eqx.Module):
    """The state split into slabs (host arrays): per device `slots` particle slots
    (ids: the state's slot of each, -1 where empty)."""

    cuts: np.ndarray
    ids: np.ndarray  # (devices, slots)
    fields: dict  # name -> (devices, slots, ...)
    slots: int
    halo_slots: int

    def shape(self, halo: float) -> tuple:
        """What the compiled program depends on besides the arrays."""
        return (self.cuts.size - 1, self.slots, self.halo_slots, halo)


def _layout(
    state: State, count: int, halo: float, slack: float, before: "_Layout | None"
) -> _Layout:
    """Cut the active particles into `count` equal counts across x, the cuts at
    least `halo` apart; slots by `slack` times the largest counts, never fewer
    than `before`'s (so that a layout like the last reuses its program)."""
    position = np.asarray(state.position)
    x = position[:, 0]
    live = np.flatnonzero(np.asarray(state.active))
    xs = np.sort(x[live])
    cuts = [xs[(k * len(xs)) // count] for k in range(1, count)]
    for k in range(1, len(cuts)):
        cuts[k] = max(cuts[k], cuts[k - 1] + halo)
    if count > 2 and cuts[-1] > xs[-1]:
        raise ValueError(
            f"{count} devices need {count - 2} inner slabs at least a halo "
            f"({halo:.4g} m) wide, more than this domain's particles span across x "
            f"({xs[-1] - xs[0]:.4g} m). Split over fewer devices (devices=...), or "
            "run a longer domain."
        )
    cuts = np.concatenate([[-np.inf], cuts, [np.inf]])
    slab = np.searchsorted(cuts, x[live], side="right") - 1
    counts = np.bincount(slab, minlength=count)
    slots = int(math.ceil(len(live) / 8) * 8)
    halo_slots = 0
    if count > 1:
        slots = int(min(slots, math.ceil(slack * counts.max() / 8) * 8))
        # The most particles in any band of the halo's width.
        reach = np.searchsorted(xs, xs + halo, side="left") - np.arange(len(xs))
        halo_slots = int(min(slots, math.ceil(slack * reach.max() / 8) * 8))
    if before is not None:
        slots, halo_slots = max(slots, before.slots), max(halo_slots, before.halo_slots)
    ids = np.full((count, slots), -1, dtype=np.int32)
    for d in range(count):
        mine = live[slab == d]
        ids[d, : len(mine)] = mine
    fields = {}
    taken = ids >= 0
    for name in _FIELDS:
        value = np.asarray(getattr(state, name))
        out = np.zeros((count, slots) + value.shape[1:], dtype=value.dtype)
        out[taken] = value[ids[taken]]
        fields[name] = out
    return _Layout(cuts, ids, fields, slots, halo_slots)


def _place(layout: _Layout, mesh: Mesh, state: State) -> tuple:
    """The program's inputs: the layout's arrays on the mesh (slab d's slots on
    device d), the cuts and the state's scalars on every device."""
    split = NamedSharding(mesh, PartitionSpec(SLABS))
    whole = NamedSharding(mesh, PartitionSpec())

    def put(value):
        flat = value.reshape((-1,) + value.shape[2:])
        return jax.device_put(flat, split)

    dtype = layout.fields["position"].dtype
    scalars = {
        k: jax.device_put(np.asarray(getattr(state, k)), whole)
        for k in ("time", "step", "dt", "acceleration", "escaped")
    }
    cuts = jax.device_put(layout.cuts.astype(dtype), whole)
    return put(layout.ids), {k: put(v) for k, v in layout.fields.items()}, scalars, cuts


@eqx.filter_jit
def _program(scene, params, mesh, shape, n_steps, ids, fields, scalars, cuts):
    """`n_steps` steps of every slab (`shard_map` over `mesh`): the final slots,
    scalars and each slab's most particles held and sent to one halo."""
    dynamic, static = eqx.partition(params, eqx.is_array)

    def local(dynamic, ids, fields, scalars, cuts):
        params = eqx.combine(dynamic, static)
        return _local_run(scene, params, shape, n_steps, ids, fields, scalars, cuts)

    spec, whole = PartitionSpec(SLABS), PartitionSpec()
    return jax.shard_map(
        local,
        mesh=mesh,
        in_specs=(whole, spec, spec, whole, whole),
        out_specs=(spec, whole, spec),
        check_vma=False,
    )(dynamic, ids, fields, scalars, cuts)


def _local_run(scene, params, shape, n_steps, ids, fields, scalars, cuts):
    """One device's part of the run (inside `shard_map`)."""
    device = jax.lax.axis_index(SLABS)
    lo, hi = cuts[device], cuts[device + 1]
    state = State(result=Result.successful, **scalars, **fields)
    peaks = jnp.zeros((2,), jnp.int32)

    def one_step(carry, _):
        state, ids, peaks = carry
        new, new_ids, sent = _slab_step(scene, params, state, ids, lo, hi, shape)
        # A failed step is not taken: the last good state stays, with the failure.
        taken = new.result == Result.successful
        state, ids = jax.tree.map(
            lambda a, b: jnp.where(taken, a, b), (new, new_ids), (state, ids)
        )
        state = dataclasses.replace(state, result=new.result)
        held = jnp.sum(new.active, dtype=jnp.int32)
        grown = jnp.maximum(peaks, jnp.stack([held, sent]))
        return (state, ids, jnp.where(taken, grown, peaks)), None

    (state, ids, peaks), _ = jax.lax.scan(
        one_step, (state, ids, peaks), None, length=n_steps
    )
    final = dict({k: getattr(state, k) for k in _FIELDS}, ids=ids)
    scalars = dict(
        time=state.time,
        step=state.step,
        dt=state.dt,
        acceleration=state.acceleration,
        escaped=state.escaped,
        code=result_code(state.result),
    )
    return final, scalars, peaks[None, :]


def _slab_step(scene, params, state, ids, lo, hi, shape):
    """One step of a slab: its halo in, the one-device step, crossings out. Returns
    the new state (its result the first failure over all slabs), ids, and the
    most particles sent to one halo."""
    count, slots, halo_slots, halo = shape
    result = state.result
    dt = None
    if scene.time_step is not None:
        dt = jax.lax.pmin(time_step(scene, params, state), SLABS)
        small = dt < scene.time_step.smallest(params)
        result = update_result(result, small, Result.time_step_below_minimum)
    if count == 1:
        new, _ = _step(
            scene, params, dataclasses.replace(state, result=result), None, dt
        )
        return new, ids, jnp.zeros((), jnp.int32)
    fields = {k: getattr(state, k) for k in _FIELDS}
    x = state.position[:, 0]
    to_lower = state.active & (x < lo + halo)
    to_upper = state.active & (x >= hi - halo)
    sent = jnp.maximum(jnp.sum(to_lower), jnp.sum(to_upper)).astype(jnp.int32)
    from_upper, from_lower, overflow = _swap(
        fields, to_lower, to_upper, halo_slots, count
    )
    extended = {
        k: jnp.concatenate([fields[k], from_lower[k], from_upper[k]]) for k in _FIELDS
    }
    result = update_result(result, overflow, Result.slab_overflow)
    ext = dataclasses.replace(state, result=result, **extended)
    counted = jnp.arange(slots + 2 * halo_slots) < slots
    new, _ = _step(scene, params, ext, None, dt, counted)
    mine = {k: getattr(new, k)[:slots] for k in _FIELDS}
    # Crossings: out of this slab into the neighbours' free slots.
    x = mine["position"][:, 0]
    down = mine["active"] & (x < lo)
    up = mine["active"] & (x >= hi)
    came_down, came_up, crowded = _swap(
        dict(mine, ids=ids), down, up, halo_slots, count
    )
    mine["active"] = mine["active"] & ~(down | up)
    mine["ids"] = jnp.where(down | up, -1, ids)
    mine, full = _insert(mine, came_up, came_down, slots=slots)
    ids = mine.pop("ids")
    full = jax.lax.psum(full.astype(jnp.int32), SLABS) > 0
    result = update_result(new.result, crowded | full, Result.slab_overflow)
    new = dataclasses.replace(
        new,
        acceleration=jax.lax.pmax(new.acceleration, SLABS),
        escaped=state.escaped + jax.lax.psum(new.escaped - state.escaped, SLABS),
        result=_first_failure(result),
        **mine,
    )
    return new, ids, sent


def _swap(fields, down, up, slots, count):
    """Send the particles flagged `down` to the slab below and those flagged `up`
    to the slab above (`slots` each); returns (from the slab above, from the
    slab below, any overflow of the sends)."""
    low, low_over = _pack(fields, down, slots)
    high, high_over = _pack(fields, up, slots)
    downwards = [(d, d - 1) for d in range(1, count)]
    from_above = _unbundle(jax.lax.ppermute(_bundle(low), SLABS, downwards), low)
    upwards = [(d, d + 1) for d in range(count - 1)]
    from_below = _unbundle(jax.lax.ppermute(_bundle(high), SLABS, upwards), high)
    overflow = jax.lax.psum((low_over | high_over).astype(jnp.int32), SLABS) > 0
    return from_above, from_below, overflow


def _bundle(fields: dict) -> tuple:
    """The fields as one float and one integer array (columns in key order): two
    transfers instead of one per field (each is a synchronisation)."""
    floats = [v.reshape(v.shape[0], -1) for v in fields.values() if _is_float(v)]
    ints = [
        v.reshape(v.shape[0], -1).astype(jnp.int32)
        for v in fields.values()
        if not _is_float(v)
    ]
    return jnp.concatenate(floats, axis=1), jnp.concatenate(ints, axis=1)


def _unbundle(bundle: tuple, like: dict) -> dict:
    """`_bundle`'s inverse, shapes and dtypes taken from `like`."""
    out, columns = {}, {True: 0, False: 0}
    for k, v in like.items():
        kind = _is_float(v)
        width = int(np.prod(v.shape[1:], dtype=int))
        start = columns[kind]
        piece = bundle[0 if kind else 1][:, start : start + width]
        out[k] = piece.reshape(v.shape).astype(v.dtype)
        columns[kind] = start + width
    return out


def _is_float(value) -> bool:
    return jnp.issubdtype(value.dtype, jnp.floating)


def _pack(fields, mask, slots):
    """The flagged particles' fields in `slots` slots (inactive where empty), and
    whether more were flagged."""
    n = mask.shape[0]
    index = jnp.nonzero(mask, size=slots, fill_value=n)[0]
    taken = {
        k: jnp.take(v, index, axis=0, mode="fill", fill_value=0)
        for k, v in fields.items()
    }
    taken["active"] = taken["active"] & (index < n)
    return taken, jnp.sum(mask) > slots


def _insert(mine, *arrivals_from, slots):
    """`mine` with the arriving particles in its free slots, and whether they
    did not all fit."""
    arrived = {k: jnp.concatenate([a[k] for a in arrivals_from]) for k in mine}
    valid = arrived["active"]
    total = valid.shape[0]
    order = jnp.nonzero(valid, size=total, fill_value=total)[0]
    free = jnp.nonzero(~mine["active"], size=total, fill_value=slots)[0]
    coming = jnp.sum(valid)
    target = jnp.where(jnp.arange(total) < coming, free, slots)
    out = {}
    for k, v in mine.items():
        value = jnp.take(arrived[k], order, axis=0, mode="fill", fill_value=0)
        out[k] = v.at[target].set(value, mode="drop")
    return out, coming > jnp.sum(~mine["active"])


def _first_failure(result: Result) -> Result:
    """Every slab's result made the first failure over the slabs (lowest device
    first), so that all stop together."""
    code = result_code(result)
    failed = code != 0
    key = jnp.where(failed, jax.lax.axis_index(SLABS) * 1024 + code, 2**30)
    first = jax.lax.pmin(key, SLABS)
    code = jnp.where(first == 2**30, 0, first % 1024)
    return traced_result(code)


def _gathered(start: State, layout: _Layout, final: dict, scalars: dict) -> State:
    """The state after a save interval, in `start`'s slot order (host)."""
    ids = final["ids"]
    taken = ids >= 0
    fields = {}
    for k in _FIELDS:
        out = np.array(getattr(start, k), copy=True)
        out[ids[taken]] = final[k][taken]
        fields[k] = jnp.asarray(out)
    code = int(scalars.pop("code"))
    return dataclasses.replace(
        start,
        result=result_from_code(code),
        **{k: jnp.asarray(v) for k, v in scalars.items()},
        **fields,
    )
