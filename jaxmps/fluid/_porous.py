"""Porous damping regions (seed 001 eq. 5.1): a resistance on the fluid velocity
inside boxes that stand for perforated plates, screens or baffles too fine to
resolve with particles.

Inside region i, on the velocity component along its direction (or on the whole
velocity), relative to the walls the region is fixed to,

    du/dt = ... - u / kappa_i - c_i |u| u,

kappa_i [s] the seed's permeability coefficient (the e-folding time of the
linear resistance) and c_i [1/m] an optional quadratic (Forchheimer) drag, which
the seed suggests for thin regions that fast particles cross in a few steps.

# Choice: the seed does not say where the resistance enters; it enters the
# predictor (with viscosity and gravity, before the pressure), acting on the
# velocity at the start of the step, integrated backward in time over the step
# on its own,

    u_new (1 + dt/kappa) + dt c |u_new| u_new = u^k,
    u_new = u^k 2 / (a + sqrt(a^2 + 4 b |u^k|)),  a = 1 + dt/kappa, b = dt c,

the positive root: unconditionally stable, never reversing a velocity, smooth in
kappa and c (the gradient a calibration of log kappa follows); then
u* = u_new + dt (nu lap u + g). Damping u* instead (after gravity) would damp the
part of it the pressure cancels: still water in a region would carry a
hydrostatic pressure short by the factor 1/(1 + dt/kappa) (2.4 % at the seed's
kappa = 0.01 s, dt = 2.5e-4 s); this way it carries none of the resistance.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import safe_norm
from .._types import Kind, Kinds, Mask, Positions, Scalar, Velocities

# Directions by name: an axis, the vertical (the last axis), or all components.
DIRECTIONS = ("x", "y", "z", "vertical", "all")


def direction_axis(direction: str, dim: int) -> int | None:
    """The axis a region's `direction` damps (None: all components); ValueError
    naming `porous_direction` for a name that is not one of `DIRECTIONS` or an
    axis the scene lacks."""
    if direction not in DIRECTIONS:
        raise ValueError(
            f"porous_direction={direction!r} is not a direction; valid: "
            f"{', '.join(DIRECTIONS)}."
        )
    if direction == "all":
        return None
    if direction == "vertical":
        return dim - 1
    axis = "xyz".index(direction)
    if axis >= dim:
        raise ValueError(
            f"porous_direction={direction!r} names an axis a {dim}-D scene does not "
            f"have; valid here: {', '.join('xyz'[:dim])}, vertical, all."
        )
    return axis


class PorousRegions(eqx.Module):
    """Boxes of porous resistance on the fluid (see the module docstring); their
    coefficients are `Params.porous` (`PorousParams`), one entry per region.

    Attributes:
        lower, upper: each region's box corners [m], in the frame of the walls at
            the start of the run (overlapping regions act one after another).
        axes: the axis each region damps, or None for all components.
        moving: whether the regions move with the scene's prescribed motion
            (`Scene.motion`, when it moves every wall: a shaken tank); the damped
            velocity is then relative to the walls.
    """

    lower: tuple[tuple[float, ...], ...]
    upper: tuple[tuple[float, ...], ...]
    axes: tuple[int | None, ...]
    moving: bool = False

    def __check_init__(self):
        if not (len(self.lower) == len(self.upper) == len(self.axes) > 0):
            raise ValueError(
                "PorousRegions needs one lower corner, upper corner and axis per "
                "region, and at least one region."
            )

    @property
    def count(self) -> int:
        return len(self.axes)


def resistance_factor(
    speed: Float[Array, " n"], dt: Scalar, kappa: Scalar, drag: Scalar
) -> Float[Array, " n"]:
    """u_new / u* of the backward-Euler resistance over one step (module
    docstring) for the damped speed |u*|."""
    a = 1.0 + dt / kappa
    return 2.0 / (a + jnp.sqrt(a * a + 4.0 * dt * drag * speed))


def damp(
    regions: PorousRegions,
    kappa: Float[Array, " r"],
    drag: Float[Array, " r"],
    dt: Scalar,
    shift: Float[Array, " d"],
    frame_velocity: Float[Array, " d"],
    position: Positions,
    velocity: Velocities,
    kind: Kinds,
    active: Mask,
) -> Velocities:
    """The `velocity` after each region's resistance over `dt`, on the active fluid
    particles whose `position` lies in a box moved by `shift` (the walls'
    displacement), relative to `frame_velocity` (the walls' velocity)."""
    fluid = active & (kind == int(Kind.FLUID))
    for i in range(regions.count):
        lower = jnp.asarray(regions.lower[i], position.dtype) + shift
        upper = jnp.asarray(regions.upper[i], position.dtype) + shift
        within = (position >= lower[None, :]) & (position < upper[None, :])
        inside = fluid & jnp.all(within, axis=-1)
        relative = velocity - frame_velocity[None, :]
        axis = regions.axes[i]
        if axis is None:
            # 0 at rest, with a finite derivative there
            speed = safe_norm(relative, jnp.ones_like(inside), placeholder=0.0)
            factor = resistance_factor(speed, dt, kappa[i], drag[i])
            damped = relative * factor[:, None]
        else:
            component = relative[:, axis]
            factor = resistance_factor(jnp.abs(component), dt, kappa[i], drag[i])
            damped = relative.at[:, axis].set(component * factor)
        damped = damped + frame_velocity[None, :]
        velocity = jnp.where(inside[:, None], damped, velocity)
    return velocity
