"""Rollouts: nested `lax.scan` with checkpointing, an observe function, and `throw`."""

import inspect
from collections.abc import Callable
from typing import Any, Literal

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, Float, PyTree

from ._checks import check_compatible
from ._params import Params
from ._result import Result
from ._scene import Scene
from ._state import State
from ._step import _step, with_neighbour_lists, without_neighbour_lists


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


class Trajectory(eqx.Module):
    """Output of `simulate`.

    Attributes:
        state: the final state.
        saved: observations stacked along a leading time axis (one per save).
        result: the first failure of the rollout, or `Result.successful`.
    """

    state: State
    saved: PyTree
    result: Result


def simulate(
    scene: Scene,
    params: Params,
    state: State,
    n_steps: int,
    save_every: int | None = None,
    observe: Callable[[Scene, State], PyTree] = frame,
    *,
    throw: bool = True,
    checkpoint: bool | Literal["steps"] = True,
    batch_axis: str | None = None,
) -> Trajectory:
    """Run `n_steps` steps, observing the state every `save_every` steps.

    The loop is two nested `lax.scan`s: the outer one over saves, the inner one over
    `save_every` steps. With `checkpoint=True` the outer body is wrapped in
    `jax.checkpoint`, so reverse-mode memory grows like (number of saves + save_every)
    instead of n_steps; choose save_every ~ sqrt(n_steps) for the least memory. The
    neighbour search is recomputed in the backward pass. With `checkpoint="steps"`
    each step is checkpointed as well: the block being re-run then stores states,
    not the residuals of its steps (tens of arrays of shape (particles, slots) per
    step), for one more forward evaluation of each step in the backward pass.

    Args:
        scene, params, state: the simulation (see `make_scene`, `make_params`,
            `make_state`, or a `jaxmps.scenes` case).
        n_steps: number of steps; a multiple of `save_every`.
        save_every: steps between observations (default: n_steps, one save at the end).
        observe: `(scene, state) -> PyTree` saved after every `save_every` steps. Pass a
            module-level function (a new lambda per call recompiles). Default: `frame`.
        throw: raise at the end if the rollout failed (neighbour overflow, pressure
            solve not converged, non-finite state, particle left the domain, step too
            large).
            Errors are only reliably raised on CPU; on GPU they may only be printed.
            Under `vmap`, an error is raised if any batch member fails: prefer
            `throw=False` and inspect `Trajectory.result`.
        checkpoint: rematerialise each save block in the backward pass (True), also
            each step ("steps": least memory, slower gradient; it also searches for
            neighbours twice per step instead of carrying the lists), or nothing
            (False: most memory, memory ~ n_steps).
        batch_axis: when this call runs under `jax.vmap(..., axis_name=name)`,
            `name`: the members then decide together whether a step can use the
            neighbour lists carried from the previous one, which keeps that saving
            (under a plain `vmap` the choice becomes a select that searches for
            every member). `jaxmps.sweep` does this.

    Returns:
        A `Trajectory`.

    Raises:
        ValueError: at trace time, for inconsistent arguments.
        EquinoxRuntimeError: at run time with `throw=True`, with the failure's message.
    """
    # Checks run here, in Python and before tracing, so that concrete Params (dt,
    # sound speed, ...) can be refused with a ValueError; inside a user's own jit
    # they are tracers and only the run-time result codes apply.
    check_compatible(scene, params, state)
    _check_steps(n_steps, save_every)
    _check_checkpoint(checkpoint)
    return _simulate(
        scene,
        params,
        state,
        n_steps,
        save_every,
        observe,
        throw=throw,
        checkpoint=checkpoint,
        batch_axis=batch_axis,
    )


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


def _check_checkpoint(checkpoint) -> None:
    if checkpoint not in (True, False, "steps"):
        raise ValueError(
            f"checkpoint must be True, False or 'steps', got {checkpoint!r}."
        )


def lower_simulate(*args, **kwargs) -> jax.stages.Lowered:
    """The rollout `simulate(*args, **kwargs)` would run, lowered but not compiled,
    after the same checks: `.compile()` times compilation apart from running (as
    the benchmarks do). Call the compiled program with exactly the same arguments.
    """
    bound = inspect.signature(simulate).bind(*args, **kwargs)
    bound.apply_defaults()
    a = bound.arguments
    check_compatible(a["scene"], a["params"], a["state"])
    _check_steps(a["n_steps"], a["save_every"])
    _check_checkpoint(a["checkpoint"])
    return _simulate.lower(*args, **kwargs)


@eqx.filter_jit
def _simulate(
    scene: Scene,
    params: Params,
    state: State,
    n_steps: int,
    save_every: int | None,
    observe: Callable[[Scene, State], PyTree],
    *,
    throw: bool = True,
    checkpoint: bool | Literal["steps"] = True,
    batch_axis: str | None = None,
) -> Trajectory:
    save_every = n_steps if save_every is None else save_every

    def one_step(carry: State, _):
        carry, _ = _step(scene, params, carry, batch_axis)
        return carry, None

    if checkpoint == "steps":
        one_step = jax.checkpoint(one_step)

    def block(carry: State, _):
        carry, _ = jax.lax.scan(one_step, carry, None, length=save_every)
        return carry, observe(scene, without_neighbour_lists(carry))

    if checkpoint:
        block = jax.checkpoint(block)
    # Choice: `checkpoint="steps"` (least memory) carries no neighbour lists: the
    # backward pass would store them with every step's state (~0.3 MB per state of
    # 2.9k particles: 26 -> 60 MiB at T = 4000, benchmarks/NOTES.md §8).
    if checkpoint != "steps":
        state = with_neighbour_lists(scene, state)
    final, saved = jax.lax.scan(block, state, None, length=n_steps // save_every)
    final = without_neighbour_lists(final)
    out = Trajectory(state=final, saved=saved, result=final.result)
    if throw:
        out = final.result.error_if(out, final.result != Result.successful)
    return out
