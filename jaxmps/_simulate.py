"""Rollouts: saves in a `lax.scan`, each a scan of fixed steps or a bounded,
checkpointed while loop of adaptive or timed ones; an observe function, `throw`."""

import dataclasses
import inspect
import math
from collections.abc import Callable, Sequence
from typing import Any, Literal

import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Int, PyTree

from ._checks import check_compatible
from ._numerics import is_concrete
from ._params import Params
from ._result import Result, update_result
from ._scene import Scene
from ._state import State
from ._step import _step, time_step, with_neighbour_lists, without_neighbour_lists


class Frame(eqx.Module):
    """The default observation: one full particle snapshot (and, in scenes with
    body models, what each model observes of its bodies in `bodies`: for rigid
    bodies the `RigidBodies.frame_fields`)."""

    time: Float[Array, ""]
    position: Float[Array, "n d"]
    velocity: Float[Array, "n d"]
    pressure: Float[Array, " n"]
    active: Any
    bodies: dict[str, Any] | None = None


def frame(scene: Scene, state: State) -> Frame:
    """Observe a full snapshot (time, position, velocity, pressure, active, bodies)."""
    bodies = None
    if scene.body_models:
        bodies = {}
        for model in scene.body_models:
            bodies.update(model.observe(state))
    return Frame(
        time=state.time,
        position=state.position,
        velocity=state.velocity,
        pressure=state.pressure,
        active=state.active,
        bodies=bodies,
    )


class StepHistory(eqx.Module):
    """The steps behind each save (arrays with one entry per save; scalars inside
    the loop, for one save).

    Attributes:
        accepted: steps taken since the previous save.
        rejected: adaptive steps taken again with half the dt (a stability limit
            was exceeded or the state went non-finite).
        dt_min, dt_max: the smallest and largest dt of the accepted steps [s]
            (nan where none was taken).
    """

    accepted: Int[ArrayLike, "*saves"]
    rejected: Int[ArrayLike, "*saves"]
    dt_min: Float[ArrayLike, "*saves"]
    dt_max: Float[ArrayLike, "*saves"]


class Trajectory(eqx.Module):
    """Output of `simulate`.

    Attributes:
        state: the final state.
        saved: observations stacked along a leading time axis (one per save).
        result: the first failure of the rollout, or `Result.successful`.
            A rollout stops at its first failure (with either time stepping):
            the final state and every later save hold the state of the step that
            failed, and `steps.accepted` is 0 for the saves after it.
        steps: the steps behind each save (`StepHistory`).
    """

    state: State
    saved: PyTree
    result: Result
    steps: StepHistory


def simulate(
    scene: Scene,
    params: Params,
    state: State,
    n_steps: int | None = None,
    save_every: int | None = None,
    observe: Callable[[Scene, State], PyTree] = frame,
    *,
    times: ArrayLike | Sequence[float] | None = None,
    max_steps: int | None = None,
    throw: bool = True,
    checkpoint: bool | Literal["steps"] = True,
    batch_axis: str | None = None,
    autodiff: Literal["reverse", "forward"] = "reverse",
) -> Trajectory:
    """Run `n_steps` steps, observing every `save_every` steps; or run to each of
    `times`, observing there.

    Each step's dt is `Params.dt`, or with `Scene.time_step = Adaptive()` the
    flow's own limit (at most `Params.dt`; see `jaxmps.Adaptive`). With `times`
    the last step before each save time is shortened (and the one before it
    evened with it) so that the saves are exactly at those times.

    Steps to a fixed count with fixed dt are two nested `lax.scan`s: the outer
    one over saves, the inner one over `save_every` steps. Otherwise the steps of
    a save run in a bounded while loop (at most `max_steps` attempts) that is
    reverse-differentiable by online checkpointing (`equinox.internal.while_loop`,
    as Diffrax runs adaptive solvers): its memory is a fixed number of states
    (16; 4 with `checkpoint="steps"`), whatever the number of steps. With
    `checkpoint=True` the outer body is wrapped in `jax.checkpoint`, so reverse-mode
    memory grows like (number of saves + steps per save) instead of n_steps;
    choose save_every ~ sqrt(n_steps) for the least memory. The neighbour search
    is recomputed in the backward pass. With `checkpoint="steps"` each step is
    checkpointed as well: the block being re-run then stores states, not the
    residuals of its steps (tens of arrays of shape (particles, slots) per step),
    for one more forward evaluation of each step in the backward pass.

    Args:
        scene, params, state: the simulation (see `make_scene`, `make_params`,
            `make_state`, or a `jaxmps.scenes` case).
        n_steps: number of steps; a multiple of `save_every`. Not with `times`.
        save_every: steps between observations (default: n_steps, one save at the
            end).
        observe: `(scene, state) -> PyTree` saved at every save. Pass a
            module-level function (a new lambda per call recompiles). Default: `frame`.
        times: the save times [s], increasing and after `state.time` (their number
            fixes the output's shape; their values may change without
            recompiling). Instead of `n_steps` and `save_every`.
        max_steps: the most step attempts per save before the run ends with
            `Result.too_many_steps` (default: with `times`, 20 times the steps
            of `Params.dt` in the longest interval, plus 100, or 10 000 when those
            are traced; with `n_steps`, 2 save_every + 100).
        throw: raise at the end if the rollout failed (neighbour overflow, pressure
            solve not converged, non-finite state, particle left the domain, step too
            large or, adaptive, too small).
            Errors are only reliably raised on CPU; on GPU they may only be printed.
            Under `vmap`, an error is raised if any batch member fails: prefer
            `throw=False` and inspect `Trajectory.result`.
        checkpoint: rematerialise each save block in the backward pass (True), also
            each step ("steps": least memory, slower gradient; it also searches for
            neighbours twice per step instead of carrying the lists), or nothing
            (False: most memory, memory ~ n_steps).
        autodiff: "reverse" (default: `jax.grad`, `jax.vjp`) or "forward"
            (`jax.jvp`, `jax.jacfwd`: a run's memory whatever its length, about
            one more run's work per direction, no checkpoints; such a rollout
            cannot be reverse-differentiated). The steps are the same either
            way; only adaptive or timed rollouts need the choice.
        batch_axis: when this call runs under `jax.vmap(..., axis_name=name)`,
            `name`: the members then decide together whether a step can use the
            neighbour lists carried from the previous one, which keeps that saving
            (under a plain `vmap` the choice becomes a select that searches for
            every member). `jaxmps.sweep` does this. Under `vmap`, members may
            take different numbers of steps.

    Returns:
        A `Trajectory`.

    Raises:
        ValueError: at trace time, for inconsistent arguments.
        EquinoxRuntimeError: at run time with `throw=True`, with the failure's message.
    """
    args, kwargs = _prepared(
        scene,
        params,
        state,
        n_steps,
        save_every,
        observe,
        times=times,
        max_steps=max_steps,
        throw=throw,
        checkpoint=checkpoint,
        batch_axis=batch_axis,
        autodiff=autodiff,
    )
    return _simulate_naming_the_mode(args, kwargs)


def _simulate_naming_the_mode(args: tuple, kwargs: dict) -> Trajectory:
    """`_simulate`, with JAX's refusal of forward mode through the checkpointed
    while loop (it names a custom_vjp) turned into the setting to change."""
    try:
        return _simulate(*args, **kwargs)
    except TypeError as error:
        if "forward-mode" not in str(error):
            raise
        raise TypeError(
            "This rollout (adaptive time steps, or save `times`) is set up for "
            "reverse-mode derivatives (jax.grad, jax.jacrev, jax.vjp); for forward "
            "mode (jax.jvp, jax.jacfwd) call simulate(..., autodiff='forward')."
        ) from None


def _prepared(*args, **kwargs) -> tuple[tuple, dict]:
    """`simulate`'s arguments checked and completed (the defaults that depend on
    them), as `_simulate` takes them.

    Checks run here, in Python and before tracing, so that concrete Params (dt,
    sound speed, ...) can be refused with a ValueError; inside a user's own jit
    they are tracers and only the run-time result codes apply.
    """
    bound = inspect.signature(simulate).bind(*args, **kwargs)
    bound.apply_defaults()
    a = dict(bound.arguments)
    check_compatible(a["scene"], a["params"], a["state"])
    a["n_steps"], a["save_every"], a["max_steps"] = _check_loop(
        a["params"],
        a["state"],
        a["n_steps"],
        a["save_every"],
        a["times"],
        a["max_steps"],
    )
    _check_checkpoint(a["checkpoint"])
    check_autodiff(a["autodiff"])
    if a["times"] is not None:
        a["times"] = jnp.asarray(a["times"], a["state"].time.dtype)
    positional = ("scene", "params", "state", "n_steps", "save_every", "observe")
    return tuple(a.pop(k) for k in positional), a


def _check_loop(
    params: Params,
    state: State,
    n_steps: int | None,
    save_every: int | None,
    times: ArrayLike | Sequence[float] | None,
    max_steps: int | None,
) -> tuple[int | None, int | None, int]:
    """Check the loop's arguments (ValueError naming the one to change); the
    step count, steps per save and the bound on steps per save."""
    if times is None:
        if n_steps is None:
            raise ValueError(
                "simulate needs `n_steps` (a number of steps) or `times` (the "
                "save times [s])."
            )
        _check_steps(n_steps, save_every)
        save_every = n_steps if save_every is None else save_every
        if max_steps is None:
            max_steps = 2 * save_every + 100
    else:
        if n_steps is not None or save_every is not None:
            raise ValueError(
                "Give either `times` (the save times [s]) or `n_steps` and "
                "`save_every`, not both."
            )
        _check_times(times, state)
        if max_steps is None:
            max_steps = _default_max_steps(times, params, state)
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)):
        raise ValueError(f"max_steps must be a whole number, got {max_steps!r}.")
    if max_steps < 1 or (times is None and max_steps < save_every):
        raise ValueError(
            f"max_steps={max_steps} must be at least 1 and at least save_every."
        )
    return n_steps, save_every, int(max_steps)


def _check_times(times: ArrayLike | Sequence[float], state: State) -> None:
    """Save times: a 1-D array; concrete ones finite, increasing, after the
    state's time."""
    shape = np.shape(times)
    if len(shape) != 1 or shape[0] < 1:
        raise ValueError(
            f"times must be a 1-D array of save times [s], got shape {shape}."
        )
    if not is_concrete(times):
        return
    values = np.asarray(times, dtype=float)
    if not np.all(np.isfinite(values)):
        raise ValueError(f"times must be finite, got {values.tolist()}.")
    if np.any(np.diff(values) <= 0):
        raise ValueError(f"times must increase, got {values.tolist()}.")
    if is_concrete(state.time) and not values[0] > float(np.asarray(state.time)):
        raise ValueError(
            f"times[0]={values[0]:g} s must come after the state's time "
            f"{float(np.asarray(state.time)):g} s."
        )


def _default_max_steps(
    times: ArrayLike | Sequence[float], params: Params, state: State
) -> int:
    """20 times the steps of `Params.dt` in the longest save interval, plus 100
    (10 000 when they are traced)."""
    if not is_concrete(times, params.dt, state.time):
        return 10_000
    edges = np.concatenate([[float(np.asarray(state.time))], np.asarray(times, float)])
    longest = float(np.max(np.diff(edges)))
    dt = float(np.min(np.asarray(params.dt)))
    return int(min(20 * math.ceil(longest / dt) + 100, _MAX_ATTEMPTS))


# Steps and attempts are counted in int32.
_MAX_ATTEMPTS = 2**31 - 1


def _check_steps(n_steps: int, save_every: int | None) -> None:
    save_every = n_steps if save_every is None else save_every
    for name, value in (("n_steps", n_steps), ("save_every", save_every)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(
                f"{name} must be a whole number of steps, got {value!r} "
                f"({type(value).__name__})."
            )
    if save_every < 1 or n_steps < 1 or n_steps % save_every:
        raise ValueError(
            f"n_steps={n_steps} must be a positive multiple of save_every={save_every}."
        )


def check_autodiff(autodiff) -> None:
    """`autodiff` is "reverse" or "forward" (ValueError naming it otherwise)."""
    if autodiff not in ("reverse", "forward"):
        raise ValueError(
            f"autodiff must be 'reverse' (jax.grad) or 'forward' (jax.jvp, "
            f"jax.jacfwd), got {autodiff!r}."
        )


def _check_checkpoint(checkpoint) -> None:
    if checkpoint not in (True, False, "steps"):
        raise ValueError(
            f"checkpoint must be True, False or 'steps', got {checkpoint!r}."
        )


def lower_simulate(*args, **kwargs) -> "LoweredRollout":
    """The rollout `simulate(*args, **kwargs)` would run, lowered but not compiled,
    after the same checks: `.compile()` times compilation apart from running (as
    the benchmarks do). Call the compiled program with exactly the same arguments.
    """
    inner_args, inner_kwargs = _prepared(*args, **kwargs)
    return LoweredRollout(_simulate.lower(*inner_args, **inner_kwargs))


class LoweredRollout:
    """A lowered rollout (`lower_simulate`): `compile()` gives a program called
    with `simulate`'s own arguments; anything else is the lowered program's
    (`as_text`, `cost_analysis`, ...)."""

    def __init__(self, lowered: Any):
        self._lowered = lowered

    def compile(self) -> Callable[..., Trajectory]:
        compiled = self._lowered.compile()

        def call(*args, **kwargs) -> Trajectory:
            inner_args, inner_kwargs = _prepared(*args, **kwargs)
            return compiled(*inner_args, **inner_kwargs)

        return call

    def __getattr__(self, name: str) -> Any:
        return getattr(self._lowered, name)


# Choice: the steps of a save run in a bounded while loop, reverse-differentiable
# by online checkpointing (`equinox.internal.while_loop(kind="checkpointed")`,
# what Diffrax runs adaptive solvers with). A scan over `max_steps` slots with
# skipped tails would be differentiable too, but it pays for every slot under
# `vmap` (a skipped step becomes a select that computes it), and its backward
# pass stores a step's residuals per slot; the while loop runs as many attempts
# as the slowest member needs and stores `_CHECKPOINTS` states.
_CHECKPOINTS = {True: 16, False: 16, "steps": 4}
# A step may stretch by this fraction to land on a save time.
_LANDING_SLACK = 1e-5


class _Attempts(eqx.Module):
    """The carry of a save's while loop: the state, the dt cap a rejected step
    left (inf: none), and the counts behind the save."""

    state: State
    retry: Float[Array, ""]
    attempts: Int[Array, ""]
    accepted: Int[Array, ""]
    rejected: Int[Array, ""]
    dt_min: Float[Array, ""]
    dt_max: Float[Array, ""]


def _where(pred, on_true: State, on_false: State) -> State:
    return jax.tree.map(lambda a, b: jnp.where(pred, a, b), on_true, on_false)


def _retried(result: Result) -> Bool[Array, ""]:
    """Whether an adaptive step ending with `result` is taken again with half the
    dt: the failures a shorter step can cure."""
    return (result == Result.step_too_large) | (result == Result.nonfinite_state)


def _advance(
    scene: Scene,
    params: Params,
    state: State,
    t_target: Float[Array, ""] | None,
    n_target: int | None,
    max_steps: int,
    checkpoints: int | None,
    batch_axis: str | None,
) -> tuple[State, StepHistory]:
    """Steps from `state` until its time reaches `t_target` (landing on it) or
    `n_target` more steps are taken, in at most `max_steps` attempts. A while
    loop checkpointed for reverse mode, or with `checkpoints=None` a plain one
    for forward mode."""
    adaptive = scene.time_step is not None
    inf = jnp.asarray(jnp.inf, state.time.dtype)
    last = None if n_target is None else state.step + n_target
    smallest = scene.time_step.smallest(params) if adaptive else None

    def going(c: _Attempts) -> Bool[Array, ""]:
        more = c.state.result == Result.successful
        if t_target is not None:
            more &= c.state.time < t_target
        if last is not None:
            more &= c.state.step < last
        return more & (c.attempts < max_steps)

    def attempt(c: _Attempts) -> _Attempts:
        old = c.state
        chosen = jnp.minimum(time_step(scene, params, old), c.retry)
        dt, landing = chosen, jnp.asarray(False)
        if t_target is not None:
            # A save interval that is a whole number of steps takes that many
            # steps, whatever the round-off in the time.
            remaining = jax.lax.stop_gradient(t_target - old.time)
            landing = remaining <= chosen * (1 + _LANDING_SLACK)
            dt = jnp.where(
                landing,
                remaining,
                jnp.where(remaining < 2 * chosen, 0.5 * remaining, chosen),
            )
        new, _ = _step(scene, params, old, batch_axis, dt)
        if t_target is not None:
            new = dataclasses.replace(new, time=jnp.where(landing, t_target, new.time))
        reject = jnp.asarray(False)
        if adaptive:
            fine = old.result == Result.successful
            reject = fine & _retried(new.result)
            too_small = fine & (chosen < smallest)
            new = _where(reject, old, new)
            given_up = dataclasses.replace(
                old,
                result=update_result(
                    old.result, too_small, Result.time_step_below_minimum
                ),
            )
            new = _where(too_small, given_up, new)
            reject &= ~too_small
        taken = ~reject & (new.step > old.step)
        return _Attempts(
            state=new,
            retry=jnp.where(reject, 0.5 * dt, inf),
            attempts=c.attempts + 1,
            accepted=c.accepted + taken,
            rejected=c.rejected + reject,
            dt_min=jnp.where(taken, jnp.minimum(c.dt_min, dt), c.dt_min),
            dt_max=jnp.where(taken, jnp.maximum(c.dt_max, dt), c.dt_max),
        )

    zero = jnp.asarray(0, jnp.int32)
    start = _Attempts(state, inf, zero, zero, zero, inf, -inf)
    if checkpoints is None:
        end = eqxi.while_loop(going, attempt, start, max_steps=max_steps, kind="lax")
    else:
        end = eqxi.while_loop(
            going,
            attempt,
            start,
            max_steps=max_steps,
            kind="checkpointed",
            checkpoints=checkpoints,
        )
    final = end.state
    unfinished = end.attempts >= max_steps
    if t_target is not None:
        unfinished &= final.time < t_target
    if last is not None:
        unfinished &= final.step < last
    final = dataclasses.replace(
        final,
        result=update_result(final.result, unfinished, Result.too_many_steps),
    )
    nan = jnp.asarray(jnp.nan, state.time.dtype)
    history = StepHistory(
        accepted=end.accepted,
        rejected=end.rejected,
        dt_min=jnp.where(end.accepted > 0, end.dt_min, nan),
        dt_max=jnp.where(end.accepted > 0, end.dt_max, nan),
    )
    return final, history


@eqx.filter_jit
def _simulate(
    scene: Scene,
    params: Params,
    state: State,
    n_steps: int | None,
    save_every: int | None,
    observe: Callable[[Scene, State], PyTree],
    *,
    times: Float[Array, " saves"] | None = None,
    max_steps: int,
    throw: bool = True,
    checkpoint: bool | Literal["steps"] = True,
    batch_axis: str | None = None,
    autodiff: Literal["reverse", "forward"] = "reverse",
) -> Trajectory:
    if autodiff == "forward":
        # Forward-mode tangents are carried along the steps: nothing to store.
        checkpoint = False
    if times is None and scene.time_step is None:
        block = _fixed_block(scene, params, save_every, observe, checkpoint, batch_axis)
        xs, length = None, n_steps // save_every
    else:

        def block(carry: State, t_target):
            carry, history = _advance(
                scene,
                params,
                carry,
                t_target,
                save_every if times is None else None,
                max_steps,
                None if autodiff == "forward" else _CHECKPOINTS[checkpoint],
                batch_axis,
            )
            return carry, (observe(scene, without_neighbour_lists(carry)), history)

        if times is None:
            xs, length = None, n_steps // save_every
        else:
            xs, length = times, None

    if checkpoint:
        block = jax.checkpoint(block)
    # Choice: `checkpoint="steps"` (least memory) carries no neighbour lists: the
    # backward pass would store them with every step's state (~0.3 MB per state of
    # 2.9k particles: 26 -> 60 MiB at T = 4000, benchmarks/NOTES.md §8).
    if checkpoint != "steps":
        state = with_neighbour_lists(scene, state)
    final, (saved, history) = jax.lax.scan(block, state, xs, length=length)
    final = without_neighbour_lists(final)
    out = Trajectory(state=final, saved=saved, result=final.result, steps=history)
    if throw:
        out = final.result.error_if(out, final.result != Result.successful)
    return out


def _fixed_block(
    scene: Scene,
    params: Params,
    save_every: int,
    observe: Callable[[Scene, State], PyTree],
    checkpoint: bool | Literal["steps"],
    batch_axis: str | None,
):
    """A save of `save_every` steps of `Params.dt`, as a `lax.scan`."""

    def one_step(carry: State, _):
        # A failed state is kept as it is, as the adaptive loop stops at it: the
        # steps after a failure (a particle gone, a step beyond its limit) would
        # save frames of a run that is no longer the model's.
        stepped, _ = _step(scene, params, carry, batch_axis)
        return _where(carry.result == Result.successful, stepped, carry), None

    if checkpoint == "steps":
        one_step = jax.checkpoint(one_step)

    def block(carry: State, _):
        start = carry.step
        carry, _ = jax.lax.scan(one_step, carry, None, length=save_every)
        history = StepHistory(
            accepted=carry.step - start,
            rejected=jnp.zeros_like(start),
            dt_min=params.dt,
            dt_max=params.dt,
        )
        return carry, (observe(scene, without_neighbour_lists(carry)), history)

    return block
