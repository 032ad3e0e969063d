"""Prescribed motion of wall particles: piston wave makers and shaken tanks."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._params import HarmonicParams, StrokeParams
from .._state import State


class AbstractMotionLaw(eqx.Module):
    """Displacement X(t) along the motion axis, from its Params."""

    @abc.abstractmethod
    def displacement(
        self, params: HarmonicParams | StrokeParams, time: Float[Array, ""]
    ) -> Float[Array, ""]:
        """X(time) [m]."""


class Harmonic(AbstractMotionLaw):
    """Harmonic excitation x = x0 + A sin(2 pi f (t - start)) (seed 001 §3)."""

    start: float = 0.0

    def displacement(
        self, params: HarmonicParams, time: Float[Array, ""]
    ) -> Float[Array, ""]:
        phase = 2 * jnp.pi * params.frequency * (time - self.start)
        return jnp.where(time >= self.start, params.amplitude * jnp.sin(phase), 0.0)


class Tabulated(AbstractMotionLaw):
    """A prescribed stroke history (piston wave maker)."""

    def displacement(
        self, params: StrokeParams, time: Float[Array, ""]
    ) -> Float[Array, ""]:
        return jnp.interp(time, params.times, params.stroke)


class PrescribedMotion(eqx.Module):
    """Wall and dummy particles that translate rigidly along `axis` with X(t).

    Attributes:
        particles: indices of the moving particles (static).
        axis: unit direction of the motion.
        law: the motion law; its parameters are `Params.motion`.
    """

    particles: tuple[int, ...]
    axis: tuple[float, ...]
    law: AbstractMotionLaw


def move_walls(
    motion: PrescribedMotion,
    params: HarmonicParams | StrokeParams,
    dt: Float[Array, ""],
    state: State,
) -> State:
    """Advance the moving particles from t to t + dt exactly (displacement
    difference, no drift) and give them the mean velocity of the step, which the
    viscous term and the PPE source see."""
    idx = jnp.asarray(motion.particles)
    axis = jnp.asarray(motion.axis, state.position.dtype)
    shift = motion.law.displacement(params, state.time + dt) - motion.law.displacement(
        params, state.time
    )
    position = state.position.at[idx].add(shift * axis[None, :])
    velocity = state.velocity.at[idx].set((shift / dt) * axis[None, :])
    return eqx.tree_at(lambda s: (s.position, s.velocity), state, (position, velocity))
