"""The semi-implicit MPS step (Koshizuka & Oka 1996; seed 000 §2.6 and §3)."""

import abc
import functools

import equinox as eqx
import jax.numpy as jnp

from .._params import Params
from .._result import StepInfo
from .._state import State
from .._types import PRESSURE_KINDS, is_kind
from ..bodies import (
    body_pressure_gradient,
    is_body,
    particle_density,
    with_contact,
)
from ..operators import number_density
from ._correct import pressure_gradient
from ._precondition import AbstractPreconditioner, Multigrid
from ._predict import (
    carry_neighbours,
    collide,
    is_mobile,
    neighbour_pairs,
    predict_state_velocity,
)
from ._pressure import solve_pressure
from ._source import AbstractSource, MixedSource, SourceInputs
from ._stabilise import DynamicStabilisation
from ._surface import FreeSurface, detect_surface


class AbstractSolver(eqx.Module):
    """How the fluid is advanced by one step (semi-implicit or explicit MPS)."""

    @abc.abstractmethod
    def advance(self, scene, params: Params, state: State) -> tuple[State, StepInfo]:
        """Advance fluid (and body-as-fluid) particles by `params.dt`."""

    def check_params(self, scene, params: Params) -> None:
        """Refuse, before any tracing, Params this solver cannot run (ValueError).

        Only concrete values are checked; traced ones (inside jit or vmap) are left
        to the run-time result codes.
        """
        del scene, params


class SemiImplicit(AbstractSolver):
    """Semi-implicit MPS: explicit viscosity and gravity, implicit pressure.

    Attributes:
        rtol: relative tolerance ||r|| <= rtol ||b|| of the pressure solve; `None`
            picks 1e-5 in float32 and 1e-9 in float64.
        atol: absolute tolerance on the normalised system (right-hand side scaled to
            max |b| = 1).
        max_iterations: cap on CG iterations; reaching it without converging sets
            `Result.pressure_not_converged`.
        clamp_negative_pressure: set negative pressures to zero after the solve.
        collision_distance: collision-guard distance, in units of the spacing l0;
            None switches the guard off.
        collision_restitution: coefficient of restitution of the collision guard.
        source: the PPE source term (`MixedSource()`, the seed's `DensitySource()`
            or the higher-order `HigherOrderSource()`).
        surface: free-surface detection settings.
        stabiliser: `DynamicStabilisation()` (DS, with the unshifted corrected
            gradient of the high-accuracy scheme) or None.
        preconditioner: of the pressure solve's CG: `Multigrid()` (aggregation
            V-cycle, the default) or `Jacobi()`.
    """

    rtol: float | None = None
    atol: float = 1e-12
    max_iterations: int = 2000
    # Choice: the seed does not say how negative pressures are treated. Clamping to
    # zero (as most MPS codes do) suppresses tensile clustering at the free surface
    # with the corrected gradient, which has no minimum-pressure shift.
    clamp_negative_pressure: bool = True
    collision_distance: float | None = 0.5
    collision_restitution: float = 0.2
    # Choice: the seed's source (n0 - n*)/n0 alone is unstable here (see
    # `DensitySource`); the default is the mixed source of Tanaka & Masunaga (2010).
    source: AbstractSource = MixedSource()
    surface: FreeSurface = FreeSurface()
    stabiliser: DynamicStabilisation | None = None
    # Choice: multigrid by default. Its V-cycle costs about four Jacobi iterations
    # but cuts the iterations ten- to twentyfold (benchmarks/NOTES.md §3).
    preconditioner: AbstractPreconditioner = Multigrid()

    def __check_init__(self):
        if self.rtol is not None and not 0 < self.rtol < 1:
            raise ValueError(f"SemiImplicit.rtol must lie in (0, 1), got {self.rtol}.")
        if self.max_iterations < 1:
            raise ValueError("SemiImplicit.max_iterations must be at least 1.")

    def tolerance(self, dtype) -> float:
        if self.rtol is not None:
            return self.rtol
        return 1e-9 if jnp.dtype(dtype) == jnp.float64 else 1e-5

    def advance(self, scene, params, state):
        dt = params.dt
        mobile = is_mobile(state.kind, state.active)
        # 1. Explicit part at positions r^k (eq. 2.2-3, 2.2-5).
        nbrs_k, pairs_k = neighbour_pairs(
            scene, state.position, state.active, state.neighbours
        )
        u_star = predict_state_velocity(scene, params, state, pairs_k)
        if self.collision_distance is not None:
            u_star = collide(
                u_star,
                state.kind,
                state.active,
                pairs_k,
                self.collision_distance * scene.spacing,
                self.collision_restitution,
            )
        x_star = jnp.where(
            mobile[:, None], state.position + dt * u_star, state.position
        )

        # 2. Tentative number density and free surface at r* (eq. 2.2-6, 2.4-1).
        nbrs, pairs = neighbour_pairs(scene, x_star, state.active)
        n_star = number_density(pairs)
        surface = detect_surface(
            self.surface, params.beta, scene.n0, n_star, state.kind, state.active, pairs
        )

        # 3. Pressure Poisson equation (eq. 2.2-14/15).
        # With <lap p>_i = f sum_j c_ij (p_j - p_i) (the Scene's Laplacian),
        # A p = sum_j c_ij (p_i - p_j) = -<lap p> / f, so b = -S / f for <lap p> = S.
        inputs = SourceInputs(
            pairs=pairs,
            n_star=n_star,
            u_star=u_star,
            pairs_k=pairs_k,
            n_k=number_density(pairs_k),
            velocity_k=state.velocity,
            density=params.density,
            dt=dt,
        )
        coefficient, factor = scene.laplacian.coefficients(pairs, scene)
        source = -self.source(scene, inputs) / factor
        pressure, solve_info = solve_pressure(
            pairs,
            state.kind,
            state.active,
            surface,
            source,
            state.pressure,
            self.tolerance(state.position.dtype),
            self.atol,
            self.max_iterations,
            coefficient,
            functools.partial(self.preconditioner, scene, x_star),
        )
        if self.clamp_negative_pressure:
            pressure = jnp.maximum(pressure, 0.0)

        # 4. Correction (eq. 2.2-8/9/10), pressure gradient at r*.
        grad_p = pressure_gradient(
            scene.gradient,
            pairs,
            pressure,
            state.kind,
            state.active,
            scene.n0,
            scene.dim,
        )
        contact_gradient = None
        if state.rigid is not None:
            carries = jnp.logical_and(state.active, is_kind(state.kind, PRESSURE_KINDS))
            body_gradient, contact_gradient = body_pressure_gradient(
                scene, state, pairs, pressure, carries
            )
            grad_p = jnp.where(is_body(state)[:, None], body_gradient, grad_p)
        rho = particle_density(params, state)
        u_prime = jnp.where(
            mobile[:, None], -(dt / jnp.reshape(rho, (-1, 1))) * grad_p, 0.0
        )
        if self.stabiliser is not None:
            push = self.stabiliser(
                scene,
                pairs,
                state.position,
                x_star + dt * u_prime,
                state.kind,
                state.active,
                dt,
            )
            u_prime = u_prime + dt * push
        new_state = State(
            time=state.time + dt,
            step=state.step + 1,
            position=x_star + dt * u_prime,
            velocity=u_star + u_prime,
            pressure=pressure,
            kind=state.kind,
            active=state.active,
            result=state.result,
            rigid=state.rigid,
            neighbours=carry_neighbours(state, nbrs, x_star),
        )
        if state.rigid is not None:
            new_state = with_contact(scene, new_state, pairs, contact_gradient)
        info = StepInfo(
            pressure_iterations=solve_info.iterations,
            pressure_residual=solve_info.residual,
            pressure_converged=solve_info.converged,
            neighbour_overflow=nbrs_k.neighbour_overflow | nbrs.neighbour_overflow,
            cell_overflow=nbrs_k.cell_overflow | nbrs.cell_overflow,
            outside=jnp.any(nbrs_k.outside) | jnp.any(nbrs.outside),
            surface_count=jnp.sum(surface, dtype=jnp.int32),
            unstable=jnp.asarray(False),
        )
        return new_state, info
