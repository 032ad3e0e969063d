"""Params: the differentiable, vmappable float parameters of a simulation."""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._numerics import is_concrete

# The values a Params field accepts (a field not listed must be finite):
# "positive" or ">= 0", and finite; "in (0, 1]"; ">= 0 (inf: never)", a time
# that may be infinite (a body held for good).
VALUE_RULES = {
    "density": "positive",
    "dt": "positive",
    "relaxation_step": "positive",
    "beta": "in (0, 1]",
    "sound_speed": "positive",
    "viscosity": ">= 0",
    "rigid.density": "positive",
    "rigid.mu_static": ">= 0",
    "rigid.mu_kinetic": ">= 0",
    "rigid.gyration": "positive",
    "rigid.release_time": ">= 0 (inf: never)",
    "elastic.youngs_modulus": "positive",
    "elastic.density": "positive",
    "elastic.mu_static": ">= 0",
    "elastic.mu_kinetic": ">= 0",
    "porous.kappa": "positive",
    "porous.drag": ">= 0",
    "grains.friction": ">= 0",
    "grains.restitution": "in (0, 1]",
    "grains.density": "positive",
    "grains.stiffness": "positive",
    "grains.lift": ">= 0",
    "grains.rolling": ">= 0",
    "grains.release_time": ">= 0 (inf: never)",
}


def _check_fields(module, prefix: str, where: str, nested: bool) -> None:
    """Check the concrete array fields of `module` against `VALUE_RULES` (named
    `prefix` + field), and with `nested` those of its sub-params."""
    for field in dataclasses.fields(module):
        value = getattr(module, field.name)
        name = prefix + field.name
        if value is None:
            continue
        if dataclasses.is_dataclass(value):
            if nested:
                _check_fields(value, name + ".", where, nested)
            continue
        if not is_concrete(value):
            continue
        array = np.asarray(value, dtype=float)
        rule = VALUE_RULES.get(name, "finite")
        good = np.isfinite(array)
        if rule == ">= 0 (inf: never)":  # held for good (a spin-up)
            good = array >= 0
        elif rule == "positive":
            good &= array > 0
        elif rule == ">= 0":
            good &= array >= 0
        elif rule == "in (0, 1]":
            good &= (array > 0) & (array <= 1)
        if not np.all(good):
            shown = array.item() if array.size == 1 else array.tolist()
            want = (
                "finite"
                if rule == "finite"
                else f"{rule}"
                if rule.startswith("in ") or "inf" in rule
                else f"{rule} and finite"
            )
            raise ValueError(f"{where}Params.{name} must be {want}, got {shown}.")


def check_values(params, where: str = "") -> None:
    """Refuse concrete Params values outside `VALUE_RULES` or not finite, sub-params
    included (ValueError naming the field, after `where`, e.g. a sweep member);
    traced values pass (the run-time result codes apply)."""
    _check_fields(params, "", where, nested=True)


def _optional_array(value):
    return None if value is None else jnp.asarray(value)


class InflowParams(eqx.Module):
    """Inflow parameters (differentiable): a constant inflow, or a prescribed time
    series (a tide, a long wave, a tsunami at its gauge) linearly interpolated
    between `times` and held constant outside them.

    Attributes:
        velocity: the boundary's speed along the inflow direction [m/s]; scalar,
            or one value per entry of `times`. Negative values draw water out of
            the domain through the boundary (Aida's outflow rule).
        times: sample times of the series [s], strictly increasing; None for a
            constant inflow.
        depth: the water depth the boundary feeds, over the bottom of its pressure
            layer [m]: a spawned column holds the layer's particles whose centres
            lie below it (a prescribed surface elevation). Scalar, or one value per
            entry of `times`; None for the layer's full height.
    Unit discharge q = velocity x depth.
    """

    velocity: Float[Array, "*m"] = eqx.field(converter=jnp.asarray)
    times: Float[Array, " m"] | None = eqx.field(
        default=None, converter=_optional_array
    )
    depth: Float[Array, "*m"] | None = eqx.field(
        default=None, converter=_optional_array
    )

    def __check_init__(self):
        for name in ("velocity", "depth"):
            value = getattr(self, name)
            if self.times is None or value is None:
                continue
            if tuple(value.shape) != tuple(self.times.shape):
                raise ValueError(
                    f"InflowParams.{name} has shape {tuple(value.shape)}; give one "
                    f"value per entry of `times`, shape {tuple(self.times.shape)}."
                )
        if self.times is not None and is_concrete(self.times):
            times = np.asarray(self.times, dtype=float)
            if times.ndim != 1 or times.size < 2 or not np.all(np.diff(times) > 0):
                raise ValueError(
                    "InflowParams.times must hold at least two strictly increasing "
                    f"times, got {times.tolist()}."
                )
        if self.depth is not None and is_concrete(self.depth):
            if not np.all(np.asarray(self.depth, dtype=float) >= 0):
                raise ValueError(
                    "InflowParams.depth must be >= 0 (a depth over the bottom of the "
                    "inflow boundary, not a surface level)."
                )

    def at(
        self, time: Float[Array, ""]
    ) -> tuple[Float[Array, ""], Float[Array, ""] | None]:
        """(velocity, depth) at `time`; depth is None when not prescribed."""
        if self.times is None:
            return self.velocity, self.depth
        velocity = jnp.interp(time, self.times, self.velocity)
        depth = None if self.depth is None else jnp.interp(time, self.times, self.depth)
        return velocity, depth


class HarmonicParams(eqx.Module):
    """x(t) = amplitude sin(2 pi frequency (t - start)) for t >= start, else 0.

    Attributes:
        amplitude: displacement amplitude A [m].
        frequency: frequency f [Hz].
    """

    amplitude: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    frequency: Float[Array, ""] = eqx.field(converter=jnp.asarray)


class StrokeParams(eqx.Module):
    """A tabulated stroke history, linearly interpolated (held constant outside).

    Attributes:
        times: sample times [s], increasing.
        stroke: displacement at those times [m].
    """

    times: Float[Array, " m"] = eqx.field(converter=jnp.asarray)
    stroke: Float[Array, " m"] = eqx.field(converter=jnp.asarray)


class RigidParams(eqx.Module):
    """Per-body parameters of the rigid-body component (differentiable).

    A body's mass is its density times its particles' volume. Its centre of mass
    and inertia are those of its particles (a uniform body) unless given:

    Attributes:
        density: density of each body [kg/m^3], shape (b,).
        mu_static: static friction coefficient against walls, shape (b,).
        mu_kinetic: kinetic (sliding) friction coefficient, shape (b,).
        centre_of_mass: where each body's centre of mass lies from the centroid of
            its particles, in the body frame (the frame the particles were given
            in) [m], shape (b, d); None for the centroid.
        gyration: each body's radii of gyration about its centre of mass [m], about
            z in 2-D (shape (b, 1)) and about the body-frame axes x, y, z in 3-D
            (shape (b, 3), principal axes); None for the inertia of the body's
            particles about the centre of mass.
        release_time: the time [s] until which each body is held still (the
            fluid flows round it and it reports the load it carries in
            `State.rigid.force`), shape (b,); None: every body is free from the
            start. Seed 002 spins its flumes up with the blocks held.
    """

    density: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    mu_static: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    mu_kinetic: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    centre_of_mass: Float[Array, "b d"] | None = eqx.field(
        default=None, converter=_optional_array
    )
    gyration: Float[Array, "b a"] | None = eqx.field(
        default=None, converter=_optional_array
    )
    release_time: Float[Array, " b"] | None = eqx.field(
        default=None, converter=_optional_array
    )

    def __check_init__(self):
        # Only concrete values can be checked; traced values pass through.
        _check_fields(self, "rigid.", "", nested=False)


class ElasticParams(eqx.Module):
    """Per-body parameters of the elastic-body component (differentiable).

    Attributes:
        youngs_modulus: Young's modulus E of each body [Pa], shape (b,).
        poisson_ratio: Poisson's ratio nu of each body, in (-1, 0.5), shape (b,).
        density: density of each body [kg/m^3], shape (b,).
        mu_static, mu_kinetic: each body's static and kinetic friction
            coefficients against walls, shape (b,); None when the bodies have no
            friction law (`ElasticBodies.friction`).
    """

    youngs_modulus: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    poisson_ratio: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    density: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    mu_static: Float[Array, " b"] | None = eqx.field(
        default=None, converter=_optional_array
    )
    mu_kinetic: Float[Array, " b"] | None = eqx.field(
        default=None, converter=_optional_array
    )

    def __check_init__(self):
        _check_fields(self, "elastic.", "", nested=False)


class PorousParams(eqx.Module):
    """Per-region coefficients of the porous damping regions (differentiable; see
    `jaxmps.fluid.PorousRegions`).

    Attributes:
        kappa: each region's permeability coefficient kappa [s]: the linear
            resistance -u/kappa, shape (r,). Calibrate it on a log scale.
        drag: each region's quadratic drag coefficient c [1/m] (the resistance
            -c |u| u; 0 for none), shape (r,).
    """

    kappa: Float[Array, " r"] = eqx.field(converter=jnp.asarray)
    drag: Float[Array, " r"] = eqx.field(converter=jnp.asarray)

    def __check_init__(self):
        _check_fields(self, "porous.", "", nested=False)


class GrainParams(eqx.Module):
    """Parameters of the DEM grains (differentiable; see `jaxmps.bodies.Grains`),
    one value for all the grains of a Scene.

    Attributes:
        friction: Coulomb friction coefficient mu of a contact (grain-grain and
            grain-wall); seed 002 takes 0.577 (tan 30 degrees).
        restitution: the normal coefficient of restitution e of a binary
            collision, in (0, 1]: the contact's dashpot is damped at the ratio
            -ln e / sqrt(pi^2 + ln^2 e) of its reduced mass.
        density: the grains' material density rho_s [kg/m^3]; grains in water
            are advanced with rho_s - rho_w (seed 002 §5.1).
        stiffness: the normal contact stiffness k_n [N/m]; the tangential one is
            k_n / (2 (1 + nu_p)).
        lift: the lift coefficient C_L of the fluid force (0.2 in seed 002).
        rolling: the rolling resistance coefficient mu_r: a contact resists the
            relative spin of its grains with a couple of at most mu_r R* F_n
            (0 in seed 002, whose spheres roll freely; angular sand resists).
        release_time: the time [s] until which the grains feel no fluid force:
            they settle under their own weight while the flow spins up over
            them, and the bed's grains are placed where they then lie
            (`bodies.Grains.released`); None: from the start. Seed 002 spins its
            scour runs up with the grains fixed.
    """

    friction: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    restitution: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    density: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    stiffness: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    lift: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    rolling: Float[Array, ""] = eqx.field(converter=jnp.asarray, default=0.0)
    release_time: Float[Array, ""] | None = eqx.field(
        default=None, converter=_optional_array
    )

    def __check_init__(self):
        _check_fields(self, "grains.", "", nested=False)


class Params(eqx.Module):
    """Physical coefficients. Float arrays only: changing a value never recompiles.

    Attributes:
        density: reference fluid density rho0 [kg/m^3].
        viscosity: kinematic viscosity nu [m^2/s].
        gravity: gravitational acceleration vector [m/s^2], shape (d,).
        dt: time step [s].
        beta: free-surface threshold; a particle with n* < beta * n0 is on the surface.
        sound_speed: artificial speed of sound c [m/s] of the explicit (E-MPS) equation
            of state; unused by the semi-implicit solver. The water at depth H is
            compressed by g H / c^2; a floating body (whose lattice is not) floats
            too high where that is large: the floating scenes take ten times
            sqrt(2 g H), 0.5 % (`scenes.floating_box`).
        relaxation_step: the time [s] over which the pressure source restores its
            share of the number-density error (`MixedSource.gamma`,
            `HigherOrderSource.gamma`): the source's density term is
            rho0 / (dt relaxation_step) (n0 - n) / n0, so the restoring rate per
            second, and the velocity it imposes, do not depend on the step. None
            (the default): `dt` (the source as printed, a share per step), under
            which a shorter `dt` or `dt_max` relaxes harder per second and damps
            the flow more. The scenes' setting `relaxation_step="calm"` sets it
            to the step a calm flow takes at their resolution, so that a run at a
            shorter step relaxes as gently per second as the default run.
        inflow: inflow parameters, present exactly when the Scene has an inflow.
        motion: parameters of the Scene's prescribed wall motion (`HarmonicParams`
            or `StrokeParams`), present exactly when it has one.
        rigid: per-body density and friction coefficients, present exactly when the
            Scene has rigid bodies.
        elastic: per-body Young's modulus, Poisson's ratio and density, present
            exactly when the Scene has elastic bodies.
        porous: per-region coefficients of the porous damping regions, present
            exactly when the Scene has them.
        grains: the DEM grains' friction, restitution, density, stiffness and
            lift coefficient, present exactly when the Scene has grains.
    """

    density: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    viscosity: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    gravity: Float[Array, " d"] = eqx.field(converter=jnp.asarray)
    dt: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    beta: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    sound_speed: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    relaxation_step: Float[Array, ""] | None = eqx.field(
        default=None, converter=_optional_array
    )
    inflow: InflowParams | None = None
    motion: HarmonicParams | StrokeParams | None = None
    rigid: RigidParams | None = None
    elastic: ElasticParams | None = None
    porous: PorousParams | None = None
    grains: GrainParams | None = None

    def __check_init__(self):
        # Only concrete values can be checked; traced values pass through.
        _check_fields(self, "", "", nested=False)
