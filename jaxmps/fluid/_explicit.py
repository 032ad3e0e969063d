"""The explicit pressure stage: the equation of state of weakly compressible MPS
(E-MPS, Oochi et al. 2010; seed 002)."""

from typing import ClassVar

import jax.numpy as jnp

from .._numerics import is_concrete, take_rows
from .._params import Params
from .._types import MOBILE_KINDS, PRESSURE_KINDS, Field, Kind, Scalar, is_kind
from ..neighbours import Grid
from ..operators import AbstractLaplacian, Discretisation
from ._solver import AbstractPressureSolver, PressureInputs, PressureSolution

WALL_PRESSURES = ("equation", "facing")


class Explicit(AbstractPressureSolver):
    """E-MPS: the pressure from the linear equation of state, no linear solve.

    One step (seed 002 §2.6), with the stages shared with the semi-implicit solver:
        u* = u^k + dt (nu <lap u>^k + g),  r* = r^k + dt u*;
        P_i = c^2 rho0/n0 (n*_i - n0) if n*_i > n0 else 0            (eq. 3.30/3.34);
        <grad P>_i = d/n0_grad sum_j (P_j + P_i) r_ij/|r_ij|^2 w_grad  (eq. 3.33);
        u^{k+1} = u* - dt/rho0 <grad P>,  r^{k+1} = r^k + dt u^{k+1}.
    `jaxmps.schemes.explicit()` pairs it with the E-MPS weight and gradient
    (`EMPSWeight()`, `SymmetricGradient(EMPSGradientWeight())`). The sound speed c
    is `Params.sound_speed`.

    Attributes:
        sound_courant: largest c dt / l0 accepted. Seed 002 eq. 3.40 allows 1.0;
            measured (validation/stability_map.py, a 0.2 m hydrostatic tank at
            l0 = 1 cm), runs at 0.9-1.0 stay finite but their bottom pressure is off
            by 7-35 % (the equation-of-state pressure rings), while up to 0.8 it is
            within 1.2 %; so 0.8 by default.
        check_time_step: refuse a concrete dt with c dt / l0 > sound_courant when the
            simulation starts (ValueError stating the limit). Set False to opt out;
            the run-time check (`Result.step_too_large`) stays.
        wall_pressure: how wall particles get their pressure: "equation", from
            the equation of state like fluid (seed 002 Ch. 3), or "facing", the
            pressure of the nearest fluid or body particle within r_e, 0 with
            none (seed 002 Ch. 5 and 8.2: "to make the pressure gradient zero at
            the wall, the wall particle is given the pressure of the fluid
            particle facing it").
    """

    needs_surface: ClassVar[bool] = False
    pressure_is_force: ClassVar[bool] = True
    sound_courant: float = 0.8
    check_time_step: bool = True
    wall_pressure: str = "equation"

    def __check_init__(self):
        if self.wall_pressure not in WALL_PRESSURES:
            raise ValueError(
                f"wall_pressure={self.wall_pressure!r} is not a wall pressure; "
                f"valid: {WALL_PRESSURES}."
            )

    def max_dt(self, spacing: float, sound_speed: float) -> float:
        """The sound-speed stability limit dt < sound_courant l0 / c [s]."""
        return self.sound_courant * spacing / float(sound_speed)

    def time_step_limit(self, disc: Discretisation, params: Params) -> Scalar:
        return self.sound_courant * disc.spacing / params.sound_speed

    def check_params(self, disc: Discretisation, params: Params) -> None:
        if not self.check_time_step:
            return
        dt, c = params.dt, params.sound_speed
        if is_concrete(dt) and is_concrete(c) and jnp.ndim(dt) == jnp.ndim(c) == 0:
            limit = self.max_dt(disc.spacing, float(c))
            if float(dt) > limit:
                raise ValueError(
                    f"dt={float(dt):.4g} s exceeds the explicit (E-MPS) stability "
                    "limit "
                    f"dt < {self.sound_courant:g} l0 / c = {limit:.4g} s (l0="
                    f"{disc.spacing:g} m, c={float(c):g} m/s). Reduce `dt`, or opt "
                    "out with `Explicit(check_time_step=False)`."
                )

    def __call__(
        self,
        disc: Discretisation,
        laplacian: AbstractLaplacian,
        grid: Grid,
        params: Params,
        inputs: PressureInputs,
    ) -> PressureSolution:
        del laplacian, grid
        carries = jnp.logical_and(inputs.active, is_kind(inputs.kind, PRESSURE_KINDS))
        # Free surface and spray: n* <= n0 gives P = 0 (threshold 1, eq. 3.34), as do
        # particles a free-surface model flags (none without one).
        compression = jnp.maximum(inputs.n_star - disc.n0, 0.0)
        loaded = carries & ~inputs.surface
        pressure = jnp.where(
            loaded, params.sound_speed**2 * params.density / disc.n0 * compression, 0.0
        )
        if self.wall_pressure == "facing":
            pressure = _facing(pressure, inputs)
        sound = params.sound_speed * params.dt / disc.spacing > self.sound_courant
        return PressureSolution(
            pressure=pressure,
            free=carries & ((inputs.n_star <= disc.n0) | inputs.surface),
            iterations=jnp.asarray(0, jnp.int32),
            residual=jnp.zeros((), dtype=pressure.dtype),
            converged=jnp.asarray(True),
            unstable=sound,
        )


def _facing(pressure: Field, inputs: PressureInputs) -> Field:
    """`pressure` with each wall particle's replaced by that of its nearest fluid
    or body particle within r_e (0 with none): the wall facing it."""
    pairs = inputs.pairs
    mobile = inputs.active & is_kind(inputs.kind, MOBILE_KINDS)
    candidate = pairs.valid & take_rows(mobile, pairs.index)
    distance = jnp.where(candidate, pairs.distance, jnp.inf)
    nearest = jnp.argmin(distance, axis=1)
    found = jnp.any(candidate, axis=1)
    partner = jnp.take_along_axis(pairs.index, nearest[:, None], axis=1)[:, 0]
    facing = jnp.where(found, take_rows(pressure, partner), 0.0)
    wall = inputs.active & (inputs.kind == int(Kind.WALL))
    return jnp.where(wall, facing, pressure)
