"""Trace-time checks that a Scene, Params and State belong together and can run
(ValueError naming the setting to change). Run before tracing by `step`,
`simulate` and the sweeps; inside a user's own `jit` or `vmap` the values are
tracers, and the run-time result codes apply instead."""

import jax
import jax.numpy as jnp
import numpy as np

from ._numerics import is_concrete
from ._params import Params
from ._params import check_values as check_values
from ._scene import Scene
from ._state import State


def check_compatible(scene: Scene, params: Params, state: State) -> None:
    """Trace-time check that Scene, Params and State belong together (ValueError)."""
    n, d = state.position.shape[-2:]
    if (n, d) != (scene.capacity, scene.dim):
        raise ValueError(
            f"State holds {n} particles in {d}-D but the Scene expects "
            f"{scene.capacity} in {scene.dim}-D; build both from the same case."
        )
    _check_params_shapes(scene, params)
    check_values(params)
    # Under adaptive steps Params.dt is only the largest step: the limits below
    # then bound every step instead of refusing the run.
    if scene.time_step is None:
        scene.solver.check_params(scene.discretisation, params)
    if (scene.inflow is None) != (params.inflow is None):
        raise ValueError(
            "Scene.inflow and Params.inflow must both be set or both be None."
        )
    _check_inflow_depth(scene, params, state)
    if (scene.motion is None) != (params.motion is None):
        raise ValueError(
            "Scene.motion and Params.motion must both be set or both be None."
        )
    _check_porous(scene, params)
    _check_body_models(scene, params, state)
    if scene.time_step is None:
        _check_viscous_limit(scene, params)
    _check_finite(state)


def _check_inflow_depth(scene: Scene, params: Params, state: State) -> None:
    """A prescribed inflow depth fits in the inflow boundary's pressure layer."""
    if scene.inflow is None or params.inflow.depth is None:
        return
    if not (is_concrete(params.inflow.depth) and is_concrete(state.position)):
        return
    up = scene.dim - 1
    heights = np.asarray(state.position)[..., list(scene.inflow.pressure_layer), up]
    height = float(np.max(heights) - np.min(heights)) + scene.spacing
    deepest = float(np.max(np.asarray(params.inflow.depth)))
    if deepest > height * (1 + 1e-9):
        raise ValueError(
            f"Params.inflow.depth reaches {deepest:.4g} m but the inflow boundary is "
            f"{height:.4g} m high; lower the prescribed depth (the wave height) or "
            "build a taller inflow boundary."
        )


def _check_porous(scene: Scene, params: Params) -> None:
    """Porous regions in the Scene and their coefficients in Params, one per
    region."""
    if (scene.porous is None) != (params.porous is None):
        raise ValueError(
            "Scene.porous and Params.porous must both be set or both be None; add "
            "regions with `jaxmps.add_porous_regions`."
        )
    if scene.porous is None:
        return
    count = scene.porous.count
    for name in ("kappa", "drag"):
        got = tuple(getattr(params.porous, name).shape)
        if got != (count,):
            raise ValueError(
                f"Params.porous.{name} has shape {got}; the Scene has {count} porous "
                f"region(s): give one value per region, shape ({count},)."
            )
    if scene.porous.moving and scene.motion is None:
        raise ValueError(
            "Scene.porous moves with the walls but the Scene has no prescribed "
            "motion; build the regions with `jaxmps.add_porous_regions`."
        )


def _check_body_models(scene: Scene, params: Params, state: State) -> None:
    """Each body model is present in Scene, Params and State or in none of them, and
    passes its own checks."""
    for name in scene.body_fields:
        present = {
            getattr(record, name) is not None for record in (scene, params, state)
        }
        if len(present) > 1:
            raise ValueError(
                f"Scene.{name}, Params.{name} and State.{name} must all be set or all "
                "be None; build them together (for rigid bodies with "
                "`jaxmps.add_rigid_bodies`)."
            )
    for model in scene.body_models:
        model.check(params, state)
    if scene.grains is not None and scene.time_step is None:
        scene.grains.check_body_step(params, state)


def _check_params_shapes(scene: Scene, params: Params) -> None:
    """One parameter set: scalars, and gravity with one component per axis (inside
    `vmap` the shapes seen here are those of one batch member)."""
    expected = {name: () for name in ("density", "viscosity", "dt", "beta")}
    expected["sound_speed"] = ()
    expected["gravity"] = (scene.dim,)
    for name, shape in expected.items():
        got = tuple(np.shape(getattr(params, name)))
        if got != shape:
            hint = (
                f"the Scene is {scene.dim}-D"
                if name == "gravity" and len(got) == 1
                else "simulate takes one parameter set; for a batch of values use "
                "`jaxmps.sweep` or `jax.vmap` over Params"
            )
            raise ValueError(
                f"Params.{name} has shape {got}, expected {shape}: {hint}."
            )


def _check_viscous_limit(scene: Scene, params: Params) -> None:
    """Refuse concrete (dt, viscosity) beyond `Scene.viscous_limit` (ValueError);
    traced values are checked every step instead (`Result.step_too_large`)."""
    values = (params.dt, params.viscosity)
    if not is_concrete(*values):
        return
    dt, nu = (np.asarray(v, dtype=float) for v in values)
    number = np.max(2 * scene.dim * nu * dt / scene.lam)
    if number > scene.viscous_limit:
        worst = float(np.max(nu))
        raise ValueError(
            f"dt={float(np.max(dt)):.4g} s with viscosity={worst:.4g} m^2/s exceeds "
            "the viscous stability limit 2 d nu dt / lambda <= "
            f"{scene.viscous_limit:g} "
            f"(dt <= {scene.max_viscous_dt(worst):.4g} s at this viscosity and "
            f"spacing {scene.spacing:g} m). Reduce `dt` or `viscosity`, or raise "
            "`make_scene(viscous_limit=...)` at your own risk."
        )


def _check_finite(state: State) -> None:
    """Refuse a concrete initial State with non-finite positions or velocities of
    active particles (inside jit or vmap the run-time `Result.nonfinite_state`
    applies)."""
    fields = {"position": state.position, "velocity": state.velocity}
    if not is_concrete(*fields.values(), state.active):
        return
    for name, value in fields.items():
        # Concrete arrays, possibly captured by a user's jit: evaluate eagerly and
        # bring one scalar to the host unless something is wrong.
        with jax.ensure_compile_time_eval():
            finite = jnp.all(jnp.isfinite(value), axis=-1) | ~state.active
            if bool(jnp.all(finite)):
                continue
        bad = np.nonzero(~np.asarray(finite))[-1]
        raise ValueError(
            f"State.{name} is not finite for {bad.size} active particle(s) "
            f"(first indices {bad[:5].tolist()}); fix the initial state, or restart "
            "from the last good state of a run file (`jaxmps run --restart`)."
        )
