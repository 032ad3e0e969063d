"""`jaxmps.calibrate`: fit Params to an experiment curve by gradient (optax)."""

import abc
import json
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import check_compatible, check_values
from .._result import Result, result_code, result_from_code
from .._simulate import check_autodiff, simulate
from ..scenes import Case, observe_probes
from ._fields import get_field, set_field


class Curve(eqx.Module):
    """A measured time series (its own sampling) to fit a probe to.

    Attributes:
        times: sample times [s], increasing.
        values: measured values, same length.
        weights: optional per-sample weights (default 1).
        window: optional (t_start, t_end): only samples inside count.
    """

    times: Any = eqx.field(converter=np.asarray)
    values: Any = eqx.field(converter=np.asarray)
    weights: Any = None
    window: tuple[float, float] | None = None

    def __check_init__(self):
        if self.times.shape != self.values.shape or self.times.ndim != 1:
            raise ValueError("Curve.times and Curve.values must be equal-length 1-D.")
        if np.any(np.diff(self.times) <= 0):
            raise ValueError("Curve.times must be strictly increasing.")
        for name in ("times", "values"):
            value = getattr(self, name)
            if value.size == 0 or not np.all(np.isfinite(value.astype(float))):
                raise ValueError(
                    f"Curve.{name} must be finite numbers, at least one; got "
                    f"{value.tolist()[:5]}{'...' if value.size > 5 else ''}."
                )

    def mask(self) -> np.ndarray:
        if self.window is None:
            return np.ones(self.times.shape, bool)
        lo, hi = self.window
        return (self.times >= lo) & (self.times <= hi)


def curve_loss(sim_times, sim_values, curve: Curve):
    """Weighted mean squared difference between the curve and the simulated probe,
    linearly interpolated to the curve's sample times (inside the window)."""
    mask = curve.mask()
    t = jnp.asarray(curve.times[mask])
    y = jnp.asarray(curve.values[mask])
    w = (
        jnp.ones_like(y)
        if curve.weights is None
        else jnp.asarray(np.asarray(curve.weights)[mask])
    )
    sim = jnp.interp(t, sim_times, sim_values)
    return jnp.sum(w * (sim - y) ** 2) / jnp.sum(w)


class AbstractTransform(eqx.Module):
    """Map between a parameter and the unconstrained variable optimised."""

    @abc.abstractmethod
    def forward(self, u):
        """Parameter from the unconstrained variable."""

    @abc.abstractmethod
    def inverse(self, x):
        """Unconstrained variable from the parameter."""


class Identity(AbstractTransform):
    def forward(self, u):
        return u

    def inverse(self, x):
        return x


class Log(AbstractTransform):
    """Optimise log(x): keeps a positive parameter positive, steps are relative."""

    def forward(self, u):
        return jnp.exp(u)

    def inverse(self, x):
        return jnp.log(x)


class Bounded(AbstractTransform):
    """x = low + (high - low) sigmoid(u): keeps x inside (low, high)."""

    low: float
    high: float

    def __check_init__(self):
        if not self.low < self.high:
            raise ValueError("Bounded needs low < high.")

    def forward(self, u):
        return self.low + (self.high - self.low) * jax.nn.sigmoid(u)

    def inverse(self, x):
        s = (x - self.low) / (self.high - self.low)
        return jnp.log(s) - jnp.log1p(-s)


class CalibrationResult(eqx.Module):
    """History and outcome of `calibrate`.

    Attributes:
        fields: the fitted Params field names.
        values: parameter values of the best (lowest-loss) iterate {field: float}
            among those whose rollout succeeded.
        best_loss: the loss there, and `best_iteration` (1-based).
        history: {"loss": [...], field: [...]} per iteration (values before the step).
        params: the Params of the best iterate.
        iterations: steps taken; `converged`: whether `tol` was reached.
        status: "converged", "max_iterations", or "rollout_failed": the rollout of
            iterate `iterations` failed (or its loss was not finite) and the fit
            stopped there; `message` says why and at which values.
        result: the `jaxmps.Result` code of the last rollout (0: successful).
        message: "" unless the fit stopped on a failed rollout.
    """

    fields: tuple[str, ...]
    values: dict[str, float]
    best_loss: float
    best_iteration: int
    history: dict[str, list]
    params: Any
    iterations: int
    converged: bool
    wall_time: float
    status: str = "max_iterations"
    result: int = 0
    message: str = ""

    def save(self, path) -> None:
        """Write values and history as JSON."""
        Path(path).write_text(
            json.dumps(
                dict(
                    fields=list(self.fields),
                    values=self.values,
                    best_loss=self.best_loss,
                    best_iteration=self.best_iteration,
                    history=self.history,
                    iterations=self.iterations,
                    converged=self.converged,
                    wall_time=self.wall_time,
                    status=self.status,
                    result=self.result,
                    message=self.message,
                ),
                indent=1,
            )
        )

    def plot(self, path) -> None:
        """Loss and parameters against iteration, saved as an image."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(
            1, 1 + len(self.fields), figsize=(4 * (1 + len(self.fields)), 3)
        )
        axes = np.atleast_1d(axes)
        axes[0].semilogy(self.history["loss"])
        axes[0].set(xlabel="iteration", ylabel="loss")
        for ax, name in zip(axes[1:], self.fields):
            ax.plot(self.history[name])
            ax.set(xlabel="iteration", ylabel=name)
        fig.tight_layout()
        fig.savefig(path, dpi=100)
        plt.close(fig)


def _plain(x):
    """A float for a one-element array (e.g. a per-body field of one body), else a
    list."""
    arr = np.asarray(x)
    return float(arr.reshape(())) if arr.size == 1 else arr.tolist()


def calibrate(
    case: Case,
    fields: dict[str, AbstractTransform | None],
    curve: Curve | Sequence[Curve],
    probe: str,
    n_steps: int,
    save_every: int,
    optimiser=None,
    iterations: int = 50,
    tol: float = 0.0,
    initial: dict[str, float] | None = None,
    progress: bool = True,
    checkpoint: bool | Literal["steps"] = True,
    batch: dict[str, Any] | None = None,
    mesh: Any = None,
    autodiff: Literal["reverse", "forward"] = "reverse",
) -> CalibrationResult:
    """Fit Params `fields` so that probe `probe` reproduces `curve` (or, with
    `batch`, each member's curve).

    The loss is `curve_loss` of the probe's saved time series; its gradient comes
    from reverse mode through the whole (checkpointed) rollout, or with
    `autodiff="forward"` from one forward-mode pass per fitted value. Each
    iteration is one jitted value-and-gradient call plus an optax update.

    Args:
        case: a `jaxmps.scenes.Case` (its Params are the starting point).
        fields: {Params field name: transform (`Log()`, `Bounded(lo, hi)`, or None
            for `Identity()`)}.
        curve: the measured curve.
        probe: name of one of the case's probes.
        n_steps, save_every: the rollout (as for `simulate`); the probe is saved
            every `save_every` steps.
        optimiser: an optax GradientTransformation (default `optax.adam(0.05)` on the
            unconstrained variables).
        iterations: maximum optimiser steps.
        tol: stop when the loss falls below `tol`.
        initial: optional starting values overriding the case's Params.
        progress: show a progress bar (tqdm).
        checkpoint: as for `simulate` ("steps": least memory, ~1.2-1.6x the time).
        batch: {Params field: (b,) values} of b experiments that share the fitted
            fields but differ in these (a forcing frequency, a slope, ...);
            `curve` is then a sequence of b Curves, one per member, and the loss
            their mean. The members run as one vmapped batch per device, split
            over the devices of `mesh` (default: all) as `sweep` splits them.
        mesh: a one-axis `jax.sharding.Mesh` for `batch` (default: all devices).
        autodiff: "reverse" (default) or "forward", as for `simulate`: a pass
            per fitted value (each body's, for a per-body field) and a run's
            memory; the cheaper for one or two values.

    Returns:
        A `CalibrationResult`. If the rollout of an iterate fails (a
        `jaxmps.Result` other than successful, e.g. a particle left the domain, or
        a loss that is not finite), the fit stops there with a warning: `status`
        is "rollout_failed", `result` the rollout's code, `message` names the
        iterate and its values, and `values` are the best of the iterates before.

    Raises:
        RuntimeError: if the rollout of the starting values fails (its
            `jaxmps.Result` message).
        ValueError: for an unknown probe or field, or starting values a single
            run would refuse.
    """
    import optax

    transforms, params = _starting_point(case, fields, probe, iterations, initial)
    _check_span(case, params, batch, curve, n_steps)
    optimiser = optax.adam(0.05) if optimiser is None else optimiser
    check_autodiff(autodiff)
    loop = (n_steps, save_every, checkpoint, autodiff)
    value_and_grad = (
        _single_value_and_grad(case, params, transforms, curve, probe, loop)
        if batch is None
        else _batched_value_and_grad(
            case, params, transforms, batch, curve, probe, loop, mesh
        )
    )
    u = {name: t.inverse(get_field(params, name)) for name, t in transforms.items()}
    start = time.perf_counter()
    best, history, it, code, message, converged = _optimise(
        value_and_grad, optimiser, u, transforms, iterations, tol, progress
    )
    status = "rollout_failed" if message else "converged" if converged else ""
    # Adam's momentum overshoots near the optimum: return the best iterate seen.
    fitted = _with_values(params, params, transforms, best[1])
    return CalibrationResult(
        fields=tuple(transforms),
        values={name: _plain(get_field(fitted, name)) for name in transforms},
        best_loss=best[0],
        best_iteration=best[2],
        history=history,
        params=fitted,
        iterations=it,
        converged=converged,
        wall_time=time.perf_counter() - start,
        status=status or "max_iterations",
        result=code,
        message=message,
    )


def _with_values(params, member, transforms, u):
    """`member` (Params: the starting ones, or a batch member's) with the fitted
    fields set from the unconstrained variables `u`, in the dtypes of `params`."""
    for name, t in transforms.items():
        base = get_field(params, name)
        member = set_field(member, name, t.forward(u[name]).astype(base.dtype))
    return member


def _rollout(case: Case, params, loop: tuple, batch_axis=None):
    """The probes' rollout a loss reads: (n_steps, save_every, checkpoint,
    autodiff) `loop`."""
    n_steps, save_every, checkpoint, autodiff = loop
    return simulate(
        case.scene,
        params,
        case.state,
        n_steps,
        save_every,
        observe_probes(case.probes),
        throw=False,
        checkpoint=checkpoint,
        batch_axis=batch_axis,
        autodiff=autodiff,
    )


def _value_and_derivative(loss_fn, autodiff: str):
    """`jax.value_and_grad(loss_fn, has_aux=True)` in either mode: in forward mode
    a `jax.jacfwd` (one JVP per entry of the first argument) that carries the
    value along as its aux."""
    if autodiff == "reverse":
        return jax.value_and_grad(loss_fn, has_aux=True)

    def value_and_jacfwd(*args):
        def both(*a):
            value, aux = loss_fn(*a)
            return value, (value, aux)

        derivative, value_aux = jax.jacfwd(both, has_aux=True)(*args)
        return value_aux, derivative

    return value_and_jacfwd


def _single_value_and_grad(case, params, transforms, curve, probe, loop):
    """u -> ((loss, result code), gradient) against one curve, jitted."""

    def loss_fn(u):
        run = _rollout(case, _with_values(params, params, transforms, u), loop)
        loss = curve_loss(run.saved["time"], run.saved[probe], curve)
        return loss, result_code(run.result)

    return eqx.filter_jit(_value_and_derivative(loss_fn, loop[3]))


def _starting_point(case: Case, fields, probe: str, iterations, initial):
    """The transforms of the fitted fields and the starting Params, after checking
    the arguments (ValueError naming the one to change)."""
    whole = isinstance(iterations, (int, np.integer)) and not isinstance(
        iterations, bool
    )
    if not (whole and iterations >= 1):
        raise ValueError(f"iterations must be at least 1, got {iterations!r}.")
    names = [p.name for p in case.probes]
    if probe not in names:
        raise ValueError(f"Unknown probe {probe!r}; the case has {names}.")
    transforms = {k: (Identity() if t is None else t) for k, t in fields.items()}
    params = case.params
    for name, value in (initial or {}).items():
        base = get_field(params, name)
        value = jnp.broadcast_to(jnp.asarray(value, base.dtype), base.shape)
        params = set_field(params, name, value)
    for name, transform in transforms.items():
        _check_start(name, transform, get_field(params, name))
    # The starting point passes the checks of a single run.
    check_values(params, "calibrate, starting values: ")
    check_compatible(case.scene, params, case.state)
    return transforms, params


def _check_start(name: str, transform: AbstractTransform, value) -> None:
    """A starting value the transform can invert (ValueError naming `initial`):
    Log() needs it positive (log 0 = -inf, from which no step moves), Bounded
    inside its bounds."""
    value = np.asarray(value, float)
    if isinstance(transform, Log):
        bad, rule = not np.all(value > 0), "positive (Log() fits its logarithm)"
    elif isinstance(transform, Bounded):
        bad = not np.all((value > transform.low) & (value < transform.high))
        rule = f"inside Bounded({transform.low:g}, {transform.high:g})"
    else:
        return
    if bad:
        raise ValueError(
            f"calibrate: the starting value of {name!r}, {value.tolist()}, must be "
            f"{rule}; give one in `initial` (e.g. initial={{{name!r}: ...}})."
        )


def _check_span(case: Case, params, batch, curves, n_steps: int) -> None:
    """Every sample the loss reads (inside the window, weight not 0) lies within
    the rollout: a later one would be compared with the last save held flat
    (ValueError naming n_steps and Curve.window). With adaptive steps the rollout
    may end sooner; its end with the largest step is what is checked."""
    curves = [curves] if isinstance(curves, Curve) else list(curves)
    dt = np.asarray(get_field(params, "dt"), float)
    if batch is not None and "dt" in batch:
        dt = np.asarray(batch["dt"], float)
    dts = np.broadcast_to(dt.reshape(-1), (len(curves),))
    t0 = float(np.asarray(case.state.time))
    for i, (curve, step) in enumerate(zip(curves, dts)):
        weights = np.ones(curve.times.shape) if curve.weights is None else curve.weights
        read = curve.mask() & (np.asarray(weights, float) != 0)
        if not read.any():
            continue
        last, end = float(curve.times[read].max()), t0 + n_steps * float(step)
        if last > end * (1 + 1e-9) + 1e-12:
            which = f"curve {i}" if len(curves) > 1 else "the curve"
            raise ValueError(
                f"calibrate: {which} has samples up to t={last:.6g} s, beyond the "
                f"rollout's end t={end:.6g} s ({n_steps} steps of dt={step:.4g} s "
                f"from t={t0:.6g} s), where the probe would be held at its last "
                "save; raise n_steps or leave those samples out (Curve.window)."
            )


def _failed_iterate(it: int, code: int, loss: float, history, transforms) -> str:
    """The message of a failed rollout at iterate `it`; raised (RuntimeError) for
    the first iterate, which leaves nothing to fit from, warned otherwise."""
    at = ", ".join(f"{name}={history[name][-1]}" for name in transforms)
    why = Result[result_from_code(code)] if code else f"its loss is {loss}, not finite"
    message = f"The rollout of iterate {it} ({at}) failed: {why}"
    if it == 1:
        raise RuntimeError(
            f"calibrate: {message} Nothing to fit from: change the "
            "starting values or the settings the message names."
        )
    warnings.warn(
        f"calibrate: {message} The fit stops; it returns the best of "
        f"iterates 1-{it - 1} (status 'rollout_failed').",
        stacklevel=4,
    )
    return message


def _optimise(value_and_grad, optimiser, u, transforms, iterations, tol, progress):
    """The optimiser loop: (best (loss, u, iterate), history, iterations run, the
    last rollout's result code, the failure message or "", converged)."""
    import optax

    state = optimiser.init(u)
    history = {"loss": [], **{name: [] for name in transforms}}
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=iterations, desc="calibrate", leave=False, delay=2.0)
    converged = False
    it, code, message = 0, 0, ""
    best = (np.inf, u, 0)
    try:
        for it in range(1, iterations + 1):
            (loss, code), grad = value_and_grad(u)
            loss, code = float(loss), int(code)
            history["loss"].append(loss)
            for name, t in transforms.items():
                history[name].append(_plain(t.forward(u[name])))
            if bar is not None:
                bar.update(1)
                bar.set_postfix(loss=f"{loss:.3g}")
            if code != 0 or not np.isfinite(loss):
                message = _failed_iterate(it, code, loss, history, transforms)
                break
            if loss < best[0]:
                best = (loss, u, it)
            if loss <= tol:
                converged = True
                break
            updates, state = optimiser.update(grad, state, u)
            u = optax.apply_updates(u, updates)
    finally:
        if bar is not None:
            bar.close()
    return best, history, it, code, message, converged


def _stacked_curves(curves, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The members' curves as (b, m) times, values and weights, padded to the
    longest with weight 0 (and the window applied as weight 0)."""
    if isinstance(curves, Curve) or len(curves) != b:
        raise ValueError(
            f"With `batch` of {b} members, `curve` must be a sequence of {b} "
            "Curves (one per member)."
        )
    m = max(len(c.times) for c in curves)
    t, y, w = np.zeros((b, m)), np.zeros((b, m)), np.zeros((b, m))
    for i, c in enumerate(curves):
        k = len(c.times)
        weights = np.ones(k) if c.weights is None else np.asarray(c.weights, float)
        t[i, :k], y[i, :k] = c.times, c.values
        t[i, k:], y[i, k:] = c.times[-1], c.values[-1]
        w[i, :k] = weights * c.mask()
    return t, y, w


def _batched_value_and_grad(case, params, transforms, batch, curves, probe, loop, mesh):
    """u -> ((mean loss, first failed member's result code), gradient) of a batch
    of experiments, each device computing the loss and gradient of its share."""
    import dataclasses

    from .._devices import member_mesh
    from ._sweep import _AXIS, _take, checked_batch, device_shares

    batched, axes, b = checked_batch(dataclasses.replace(case, params=params), batch)
    t, y, w = _stacked_curves(curves, b)
    local = [
        d
        for d in member_mesh(mesh).devices.flat
        if d.process_index == jax.process_index()
    ]
    devices, share = device_shares(b, local)

    def share_loss(u, p, t, y, w, real):
        def one(p, t, y, w):
            run = _rollout(case, _with_values(params, p, transforms, u), loop, _AXIS)
            sim = jnp.interp(t, run.saved["time"], run.saved[probe])
            loss = jnp.sum(w * (sim - y) ** 2) / jnp.sum(w)
            return loss, result_code(run.result)

        losses, codes = jax.vmap(one, in_axes=(axes, 0, 0, 0), axis_name=_AXIS)(
            p, t, y, w
        )
        code = jnp.max(jnp.where(real, codes, 0))
        return jnp.sum(jnp.where(real, losses, 0.0)), code

    grad_fn = eqx.filter_jit(_value_and_derivative(share_loss, loop[3]))
    pieces = []
    for k, device in enumerate(devices):
        index = np.arange(k * share, (k + 1) * share)
        real = index < b
        index = np.minimum(index, b - 1)
        inputs = (_take(batched, axes, index), t[index], y[index], w[index], real)
        dtype = jnp.asarray(get_field(params, "dt")).dtype
        inputs = jax.tree.map(
            lambda x: jnp.asarray(x, dtype) if x.dtype == np.float64 else x, inputs
        )
        pieces.append((device, jax.device_put(inputs, device)))

    def value_and_grad(u):
        parts = [grad_fn(jax.device_put(u, d), *args) for d, args in pieces]
        loss = sum(float(v) for (v, _), _ in parts) / b
        codes = [int(c) for (_, c), _ in parts if int(c)]
        grad = jax.tree.map(
            lambda *g: sum(np.asarray(x) for x in g) / b, *[g for _, g in parts]
        )
        return (loss, codes[0] if codes else 0), grad

    return value_and_grad
