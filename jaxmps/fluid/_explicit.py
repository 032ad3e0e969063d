"""The explicit, weakly compressible MPS step (E-MPS, Oochi et al. 2010; seed 002)."""

import jax
import jax.numpy as jnp
import numpy as np

from .._numerics import pair_sum, take_rows
from .._result import StepInfo
from .._state import State
from .._types import PRESSURE_KINDS, is_kind
from ..bodies import (
    contact_partners,
    particle_density,
    with_contact,
)
from ..operators import (
    AbstractWeight,
    EMPSGradientWeight,
    number_density,
    reference_constants,
)
from ._predict import (
    carry_neighbours,
    is_mobile,
    neighbour_pairs,
    predict_state_velocity,
)
from ._semi_implicit import AbstractSolver


def _concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer) and np.ndim(x) == 0


class Explicit(AbstractSolver):
    """E-MPS: pressure from the linear equation of state, no linear solve.

    One step (seed 002 §2.6):
        u* = u^k + dt (nu <lap u>^k + g),  r* = r^k + dt u*;
        P_i = c^2 rho0/n0 (n*_i - n0) if n*_i > n0 else 0            (eq. 3.30/3.34);
        <grad P>_i = d/n0_grad sum_j (P_j + P_i) r_ij/|r_ij|^2 w_grad  (eq. 3.33);
        u^{k+1} = u* - dt/rho0 <grad P>,  r^{k+1} = r^k + dt u^{k+1}.
    Use it with `EMPSWeight()` as the Scene's weight (n, Laplacian). The sound speed
    c is `Params.sound_speed`.

    Attributes:
        gradient_weight: kernel of the pressure gradient (eq. 3.6).
        sound_courant: largest c dt / l0 accepted. Seed 002 eq. 3.40 allows 1.0;
            measured (benchmarks/stability_map.py, a 0.2 m hydrostatic tank at
            l0 = 1 cm), runs at 0.9-1.0 stay finite but their bottom pressure is off
            by 7-35 % (the equation-of-state pressure rings), while up to 0.8 it is
            within 1.2 %; so 0.8 by default.
        check_time_step: refuse a concrete dt with c dt / l0 > sound_courant when the
            simulation starts (ValueError stating the limit). Set False to opt out;
            the run-time check (`Result.step_too_large`) stays.
    """

    gradient_weight: AbstractWeight = EMPSGradientWeight()
    sound_courant: float = 0.8
    check_time_step: bool = True

    def max_dt(self, scene, sound_speed: float) -> float:
        """The sound-speed stability limit dt < sound_courant l0 / c [s]."""
        return self.sound_courant * scene.spacing / float(sound_speed)

    def check_params(self, scene, params):
        if not self.check_time_step:
            return
        dt, c = params.dt, params.sound_speed
        if _concrete(dt) and _concrete(c):
            limit = self.max_dt(scene, float(c))
            if float(dt) > limit:
                raise ValueError(
                    f"dt={float(dt):.4g} s exceeds the explicit (E-MPS) stability "
                    "limit "
                    f"dt < {self.sound_courant:g} l0 / c = {limit:.4g} s (l0="
                    f"{scene.spacing:g} m, c={float(c):g} m/s). Reduce `dt`, or opt "
                    "out with `Explicit(check_time_step=False)`."
                )

    def advance(self, scene, params, state):
        dt = params.dt
        mobile = is_mobile(state.kind, state.active)
        nbrs_k, pairs_k = neighbour_pairs(
            scene, state.position, state.active, state.neighbours
        )
        u_star = predict_state_velocity(scene, params, state, pairs_k)
        x_star = jnp.where(
            mobile[:, None], state.position + dt * u_star, state.position
        )

        nbrs, pairs = neighbour_pairs(scene, x_star, state.active)
        n_star = number_density(pairs)
        carries = jnp.logical_and(state.active, is_kind(state.kind, PRESSURE_KINDS))
        # Free surface and spray: n* <= n0 gives P = 0 (threshold 1, eq. 3.34).
        # Choice: wall particles get their pressure from the equation of state like
        # fluid (seed 002 Ch. 3); the mirrored variant of Ch. 5 is not implemented.
        compression = jnp.maximum(n_star - scene.n0, 0.0)
        pressure = jnp.where(
            carries,
            params.sound_speed**2 * params.density / scene.n0 * compression,
            0.0,
        )

        n0_grad, _ = reference_constants(
            self.gradient_weight, scene.dim, scene.r_e / scene.spacing
        )
        w_grad = self.gradient_weight(pairs.distance, pairs.valid, scene.r_e)
        # Choice: dummies only complete the number density (seed 002 §2.8); they
        # carry no pressure and are left out of the gradient.
        w_grad = jnp.where(take_rows(carries, pairs.index), w_grad, 0.0)
        p_sum = take_rows(pressure, pairs.index) + pressure[:, None]
        coefficient = p_sum * w_grad / pairs.distance**2
        grad_p = (scene.dim / n0_grad) * pair_sum(coefficient, pairs.offset)

        rho = jnp.reshape(particle_density(params, state), (-1, 1))
        u_new = jnp.where(mobile[:, None], u_star - (dt / rho) * grad_p, u_star)
        # Seed 002 eq. 3.46 prints r^{k+1} = r* + dt u^{k+1}, which counts dt u* twice;
        # we use the original E-MPS update r^{k+1} = r^k + dt u^{k+1} (digest §2.6).
        x_new = jnp.where(mobile[:, None], state.position + dt * u_new, state.position)
        sound = params.sound_speed * dt / scene.spacing > self.sound_courant
        new_state = State(
            time=state.time + dt,
            step=state.step + 1,
            position=x_new,
            velocity=u_new,
            pressure=pressure,
            kind=state.kind,
            active=state.active,
            result=state.result,
            rigid=state.rigid,
            neighbours=carry_neighbours(state, nbrs, x_star),
        )
        if state.rigid is not None:
            partner = contact_partners(state, pairs)
            contact_gradient = (scene.dim / n0_grad) * pair_sum(
                jnp.where(partner, coefficient, 0.0), pairs.offset
            )
            new_state = with_contact(scene, new_state, pairs, contact_gradient)
        info = StepInfo(
            pressure_iterations=jnp.asarray(0, jnp.int32),
            pressure_residual=jnp.zeros((), dtype=x_new.dtype),
            pressure_converged=jnp.asarray(True),
            neighbour_overflow=nbrs_k.neighbour_overflow | nbrs.neighbour_overflow,
            cell_overflow=nbrs_k.cell_overflow | nbrs.cell_overflow,
            outside=jnp.any(nbrs_k.outside) | jnp.any(nbrs.outside),
            surface_count=jnp.sum(carries & (n_star <= scene.n0), dtype=jnp.int32),
            unstable=sound,
        )
        return new_state, info
