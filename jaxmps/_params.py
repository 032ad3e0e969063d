"""Params: the differentiable, vmappable float parameters of a simulation."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._numerics import is_concrete


class InflowParams(eqx.Module):
    """Inflow parameters (differentiable).

    Attributes:
        velocity: inflow speed along +x [m/s]; unit discharge q = velocity x depth.
    """

    velocity: Float[Array, ""] = eqx.field(converter=jnp.asarray)


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

    Attributes:
        density: density of each body [kg/m^3], shape (b,).
        mu_static: static friction coefficient against walls, shape (b,).
        mu_kinetic: kinetic (sliding) friction coefficient, shape (b,).
    """

    density: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    mu_static: Float[Array, " b"] = eqx.field(converter=jnp.asarray)
    mu_kinetic: Float[Array, " b"] = eqx.field(converter=jnp.asarray)

    def __check_init__(self):
        for name in ("density", "mu_static", "mu_kinetic"):
            value = getattr(self, name)
            if not is_concrete(value):
                continue
            bad = ~(value > 0) if name == "density" else ~(value >= 0)
            if bool(jnp.any(bad)):
                sign = "positive" if name == "density" else ">= 0"
                raise ValueError(
                    f"Params.rigid.{name} must be {sign} for every body, got "
                    f"{jnp.asarray(value).tolist()}."
                )


class Params(eqx.Module):
    """Physical coefficients. Float arrays only: changing a value never recompiles.

    Attributes:
        density: reference fluid density rho0 [kg/m^3].
        viscosity: kinematic viscosity nu [m^2/s].
        gravity: gravitational acceleration vector [m/s^2], shape (d,).
        dt: time step [s].
        beta: free-surface threshold; a particle with n* < beta * n0 is on the surface.
        sound_speed: artificial speed of sound c [m/s] of the explicit (E-MPS) equation
            of state; unused by the semi-implicit solver.
        inflow: inflow parameters, present exactly when the Scene has an inflow.
        motion: parameters of the Scene's prescribed wall motion (`HarmonicParams`
            or `StrokeParams`), present exactly when it has one.
        rigid: per-body density and friction coefficients, present exactly when the
            Scene has rigid bodies.
    """

    density: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    viscosity: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    gravity: Float[Array, " d"] = eqx.field(converter=jnp.asarray)
    dt: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    beta: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    sound_speed: Float[Array, ""] = eqx.field(converter=jnp.asarray)
    inflow: InflowParams | None = None
    motion: HarmonicParams | StrokeParams | None = None
    rigid: RigidParams | None = None

    def __check_init__(self):
        # Only concrete scalars can be checked; traced or batched values pass through.
        for name in ("density", "dt", "beta", "sound_speed"):
            value = getattr(self, name)
            if not is_concrete(value) or jnp.ndim(value) != 0:
                continue
            if not float(value) > 0:
                raise ValueError(f"Params.{name} must be positive, got {float(value)}.")
        if is_concrete(self.viscosity) and jnp.ndim(self.viscosity) == 0:
            if not float(self.viscosity) >= 0:
                raise ValueError(
                    f"Params.viscosity must be >= 0, got {float(self.viscosity)}."
                )
