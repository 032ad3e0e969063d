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

A region may also have a porosity phi < 1 (rock, a rubble mound: the water fills
only its pores). Its particles then move with the pore velocity and stand
sparser, phi particles per lattice site, so that the region holds phi of the
water a box of open water holds: each fluid particle's pairs weigh 1/phi(x) in
every sum of the fluid stages (`Coupling.packing`, the mechanism of seed 002's
packed-bed junction), so that the number density the pressure holds at n0 is
reached at that sparser packing. phi(x) passes from 1 to the region's value over
`transition` across each face of the box (a smoothstep, so that a particle
crossing it changes its neighbours' number density over several steps, not in
one).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._numerics import safe_norm
from .._types import Kind, Kinds, Mask, Positions, Scalar, Velocities
from ..operators._weight import lattice_offsets

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
    porosity: tuple[float, ...] | None = None
    transition: float = 0.0
    weight_table: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    def __check_init__(self):
        if not (len(self.lower) == len(self.upper) == len(self.axes) > 0):
            raise ValueError(
                "PorousRegions needs one lower corner, upper corner and axis per "
                "region, and at least one region."
            )
        if self.porosity is not None:
            if len(self.porosity) != len(self.axes):
                raise ValueError("PorousRegions needs one porosity per region.")
            if not all(0 < phi <= 1 for phi in self.porosity):
                raise ValueError(
                    f"porous_porosity must lie in (0, 1], got {self.porosity}."
                )
            if not self.transition > 0 or self.weight_table is None:
                raise ValueError(
                    "PorousRegions needs a positive transition and a weight table "
                    "with a porosity (`pore_weights`)."
                )

    @property
    def count(self) -> int:
        return len(self.axes)

    @property
    def porous(self) -> bool:
        """Whether a region has a porosity below 1 (static: a scene without one
        compiles no porosity)."""
        return self.porosity is not None and any(phi < 1 for phi in self.porosity)


# The least share of n0 that the lattice stretched to a region's porosity may
# keep by its own pairs. Below it a region's pressure is loud: in 3-D at 0.75
# (share 0.73) 28 saves in 60 were 10-28 % off, none at 0.85 (share 0.83); in
# 2-D, with the surface filter counting pore weights, single pulses of 10-45 %
# in one or two saves of 60 at 0.8 and 0.7 (shares 0.73 and 0.61), none above
# (validation/results/porous_porosity_cpu.md, still water).
LEAST_SHARE = 0.75


def _stretched_density(disc, phi: float) -> float:
    """The number density of the reference lattice stretched to spacing
    l0 phi^(-1/d), which holds phi of the water, by its own pairs."""
    dim, l0, r_e = disc.dim, disc.spacing, disc.r_e
    stretch = l0 * phi ** (-1.0 / dim)
    r = np.linalg.norm(lattice_offsets(dim, r_e / stretch), axis=1) * stretch
    return float(np.sum(np.asarray(disc.weight.value(r, r_e), np.float64)))


def lowest_porosity(disc) -> float:
    """The lowest porosity a region may have: that at which the lattice
    stretched to hold it keeps `LEAST_SHARE` of n0 by its own pairs (with the
    standard weight at r_e = 2.1 l0: 0.81 in 2-D, 0.77 in 3-D)."""
    for phi in np.arange(0.2, 1.0, 0.005):
        if _stretched_density(disc, phi) >= LEAST_SHARE * disc.n0:
            return round(float(phi), 3)
    return 1.0


def pore_weights(
    disc, samples: int = 64
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The weight a fluid particle's pairs carry at porosity phi, tabulated on
    phi from `lowest_porosity` to 1: n0 / n(phi), n(phi) the number density of
    the reference lattice stretched to spacing l0 phi^(-1/d), which holds phi of
    the water.

    # Choice: not 1/phi. The weight r_e/r - 1 makes the number density of a
    # stretched lattice fall faster than its particle count (at phi = 0.8 in 2-D,
    # n/n0 = 0.74, not 0.8): weighted 1/phi, the water settles denser than phi."""
    phi = np.linspace(lowest_porosity(disc), 1.0, samples)
    weights = [disc.n0 / _stretched_density(disc, value) for value in phi]
    return tuple(float(v) for v in phi), tuple(weights)


def _ramp(s):
    """0 below 0, 1 above 1, the smoothstep 3 s^2 - 2 s^3 between."""
    s = jnp.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def pore_weight(regions: PorousRegions, phi: Float[Array, " n"]) -> Float[Array, " n"]:
    """The weight of a fluid particle's pairs at porosity `phi` (`pore_weights`,
    interpolated; 1 at phi = 1)."""
    table_phi, table_weight = regions.weight_table
    return jnp.interp(
        phi, jnp.asarray(table_phi, phi.dtype), jnp.asarray(table_weight, phi.dtype)
    )


def porosity_field(
    regions: PorousRegions, shift: Float[Array, " d"], position: Positions
) -> Float[Array, " n"]:
    """phi(x) at each position: 1 outside the regions, the region's porosity
    inside, a smoothstep over `regions.transition` centred on each face of a box
    moved by `shift`; where regions overlap their fractions multiply."""
    phi = jnp.ones(position.shape[:1], position.dtype)
    if not regions.porous:
        return phi
    width = regions.transition
    for i in range(regions.count):
        lower = jnp.asarray(regions.lower[i], position.dtype) + shift
        upper = jnp.asarray(regions.upper[i], position.dtype) + shift
        into = _ramp((position - lower[None, :] + 0.5 * width) / width) * _ramp(
            (upper[None, :] - position + 0.5 * width) / width
        )
        share = jnp.prod(into, axis=-1)
        phi = phi * (1.0 - (1.0 - regions.porosity[i]) * share)
    return phi


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
