"""The semi-implicit pressure stage: a pressure Poisson equation solved by
preconditioned CG (Koshizuka & Oka 1996; seed 000 §2.6 and §3)."""

import functools
from typing import ClassVar

import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import take_rows
from .._params import Params
from .._types import PRESSURE_KINDS, Field, Kind, Mask, Velocities, is_kind
from ..neighbours import Grid
from ..operators import AbstractLaplacian, Discretisation, Pairs
from ._precondition import AbstractPreconditioner, Multigrid
from ._predict import is_mobile
from ._pressure import solve_pressure
from ._solver import AbstractPressureSolver, PressureInputs, PressureSolution
from ._source import AbstractSource, DensitySource, MixedSource, SourceInputs

# The default tolerances (float32, float64) of the pressure solve, tied to what the
# discretisation can tell apart: in float64, solving to 1e-6 rather than 1e-9 moved
# neither the standing wave's period (1 cm and 5 mm) nor the still-water pressure's
# mean and noise (standard and high-accuracy schemes) by more than their spread over
# initial states perturbed by 1e-9 m, and took ~1/3 fewer CG iterations
# (validation/solve_tolerance.py, benchmarks/NOTES.md §15). Finite-difference checks
# of gradients need a converged solve: give `rtol` (the tests use 1e-13).
DEFAULT_RTOL = {False: 1e-5, True: 1e-6}


class SemiImplicit(AbstractPressureSolver):
    """Semi-implicit MPS: the pressure from a pressure Poisson equation (PPE),
    <lap P>_i = S_i over the non-surface pressure-carrying particles, P = 0 on the
    free surface, solved matrix-free by preconditioned CG and differentiated
    implicitly.

    Attributes:
        rtol: relative tolerance ||r|| <= rtol ||b|| of the pressure solve; `None`
            picks 1e-5 in float32 and 1e-6 in float64 (`DEFAULT_RTOL`).
        atol: absolute tolerance on the normalised system (right-hand side scaled to
            max |b| = 1).
        max_iterations: cap on CG iterations; reaching it without converging sets
            `Result.pressure_not_converged`.
        clamp_negative_pressure: set negative pressures to zero after the solve.
        source: the PPE source term (`MixedSource()`, the seed's `DensitySource()`
            or the higher-order `HigherOrderSource()`).
        preconditioner: of the pressure solve's CG: `Multigrid()` (aggregation
            V-cycle, the default) or `Jacobi()`.
        surface_head: the pressure of free-surface fluid and wall particles, in
            units of rho |g| l0: the head of the water above a surface particle's
            centre. 0 is the seed's P = 0 at the surface particles' centres. The
            surface particles of a body pressed like the fluid
            (`RigidBodies.pressure="fluid"`) take the same head of their own
            density where they face up, rho_body |g| l0 surface_head max(0,
            n.up) for an outward normal n, with `body_head`.
        dummy_head: continue the pressure into the dummy particles hydrostatically,
            P_j = P_i + rho0 g.(r_j - r_i), instead of the seed's zero gradient
            (the dummies drop out of the PPE), and leave gravity's uniform fall out
            of the source's velocity (mobile particles enter it as u* - dt g), so
            that still water is not read as compressed against the walls. Needs a
            source with a velocity term (not `DensitySource`).
        body_head: give the surface particles of bodies pressed like the fluid
            the surface head of their own density where they face up (True), or
            hold them at 0 (False, as the seed does).
        variable_density: weigh each pair of the PPE by rho0 / rho_ij, rho_ij =
            (rho_i + rho_j) / 2 of the densities the particles are advanced
            with (`Coupling.density`: a body's own), so that the pressure solves
            div(grad P / rho) = div(u*) / dt, which the correction
            -dt grad P_i / rho_i then meets (False: every particle weighs as the
            fluid in the PPE, as the seeds do). Pairs of the fluid alone keep
            their weight exactly; a scene without bodies is unchanged.
    """

    needs_surface: ClassVar[bool] = True
    pressure_is_force: ClassVar[bool] = False
    rtol: float | None = None
    atol: float = 1e-12
    max_iterations: int = 2000
    # Choice: the seed does not say how negative pressures are treated. Clamping to
    # zero (as most MPS codes do) suppresses tensile clustering at the free surface
    # with the corrected gradient, which has no minimum-pressure shift.
    clamp_negative_pressure: bool = True
    # Choice: the seed's source (n0 - n*)/n0 alone is unstable here (see
    # `DensitySource`); the default is the mixed source of Tanaka & Masunaga (2010).
    source: AbstractSource = MixedSource()
    # Choice: multigrid by default. Its V-cycle costs about four Jacobi iterations
    # but cuts the iterations ten- to twentyfold (benchmarks/NOTES.md §3).
    preconditioner: AbstractPreconditioner = Multigrid()
    # Choice: 0.5, not the seed's 0, on fluid and wall surface particles: the
    # hydrostatic pressure at the centre of a particle half a particle below the
    # free surface. With 0 the water's top layer is held up by its one-sided gradient
    # and still water's pressure runs out 0.48 l0 below the water's surface in the
    # interior (0.2 m tank, l0 = 1 cm; 0.27-0.49 l0 at the bottom probe in four
    # tanks); a floating body, whose waterline does not share that support, rests
    # on that pressure and displaced 0.19-1.15 l0 more water than its weight. With
    # 0.5 it displaces its weight to -0.33..+0.13 l0 (B/10-B/40,
    # validation/floating_draft.py). In still water the head is a uniform offset
    # (same motion, same noise). Applied to fluid particles alone, the dry wall
    # particles at 0 beside them made a step at every contact line, which doubled
    # the noise of the still-water pressure.
    # Choice, with `body_head`: the dry surface of a body pressed like the fluid
    # gets the head of its own density where it faces up. The body's force is the
    # sum of the fluid's gradient over its particles, which reads the pressure at
    # a dry face by extrapolating the interior field half a particle out from the
    # surface particles' centres: held at P = 0 there, the face reads -s l0 / 2
    # (s the interior slope along the normal) and the body is pushed out by
    # s l0 / 2 per unit area. Holding them at s l0 / 2 (a Robin condition, P = 0
    # at the face) needs s; at rest a floating body's interior is hydrostatic in
    # its own density (measured 0.9 rho g in a box of density ratio 0.8 at B/10),
    # so s = rho_body |g| (n.up) on a face of outward normal n. With the dry
    # faces at 0 boxes floated 0.1-0.3 l0 too high at B/10 and B/20 (ratio 0.8:
    # -0.33 / -0.30 l0 by the pressure's surface), the error in l0 not falling;
    # the pair-form bodies sum no interior field and keep 0.
    surface_head: float = 0.5
    body_head: bool = True
    # Choice: a hydrostatic wall condition, not the seed's zero-gradient dummies.
    # With a zero gradient the walls carry less than the water's weight where
    # dummies surround them: in the 3-D tank (l0 = 2 cm) the wall particles at the
    # bottom corners reach 0.959 of rho g (H - z), along the bottom edges 0.976,
    # while the water in the corner reaches 1.025. The pressure then falls towards
    # the corner, the water creeps into it and through the wall layer within ~2 s
    # of still water, and a 3-D floating box fails at 0.84 s. Continued
    # hydrostatically they reach 1.002-1.005, still water stays in the tank over
    # 3 s and the box floats (validation/floating_draft.py). The head alone would
    # count gravity twice (the source already compresses the bottom rows by the
    # step's fall against the walls), hence u* - dt g in the source.
    dummy_head: bool = True
    variable_density: bool = False

    def __check_init__(self):
        if self.rtol is not None and not 0 < self.rtol < 1:
            raise ValueError(f"SemiImplicit.rtol must lie in (0, 1), got {self.rtol}.")
        if self.max_iterations < 1:
            raise ValueError("SemiImplicit.max_iterations must be at least 1.")
        if not 0 <= self.surface_head <= 1:
            raise ValueError(
                f"SemiImplicit.surface_head must lie in [0, 1], got "
                f"{self.surface_head}."
            )
        if self.dummy_head and isinstance(self.source, DensitySource):
            raise ValueError(
                "SemiImplicit.dummy_head=True needs a source with a velocity term "
                "(MixedSource or HigherOrderSource): DensitySource has no velocity "
                "to take gravity's fall out of. Set dummy_head=False to use it."
            )

    def _surface_pressure(
        self, disc: Discretisation, params: Params, inputs: PressureInputs
    ) -> Field | None:
        """surface_head rho |g| l0 on free-surface fluid and wall particles, the
        same with the body's own density, times how far they face up, on the
        surface particles of bodies pressed like the fluid, 0 on the other
        bodies' surface particles; None when surface_head is 0."""
        if self.surface_head == 0:
            return None
        head = self.surface_head * disc.spacing * jnp.sqrt(jnp.sum(params.gravity**2))
        surface = inputs.surface & inputs.active
        water = (inputs.kind == int(Kind.FLUID)) | (inputs.kind == int(Kind.WALL))
        pressure = jnp.where(surface & water, head * params.density, 0.0)
        if inputs.coupling is None or not (self.body_head and inputs.coupling.pressed):
            return pressure
        pressed = surface & inputs.coupling.as_fluid
        carries = inputs.active & is_kind(inputs.kind, PRESSURE_KINDS)
        facing = _facing_up(inputs.pairs, carries, params.gravity)
        own = head * inputs.coupling.density * facing
        return jnp.where(pressed, own, pressure)

    def _source_velocity(self, params: Params, inputs: PressureInputs) -> Velocities:
        """The velocity the source sees: u* - dt g on mobile particles with the
        dummy head (gravity's part is in the head), u* otherwise."""
        if not self.dummy_head:
            return inputs.velocity
        mobile = is_mobile(inputs.kind, inputs.active)
        fallen = inputs.velocity - params.dt * params.gravity[None, :]
        return jnp.where(mobile[:, None], fallen, inputs.velocity)

    def _dummy_head(
        self, params: Params, inputs: PressureInputs, coefficient
    ) -> Field | None:
        """sum over dummy neighbours j of c_ij rho0 g.(r_j - r_i): the right-hand
        side a system row gains when its dummies carry P_i + rho0 g.(r_j - r_i)
        (their P_i terms cancel the row's diagonal share); None without the head."""
        if not self.dummy_head:
            return None
        pairs = inputs.pairs
        dummy = inputs.active & (inputs.kind == int(Kind.DUMMY))
        c = jnp.where(pairs.valid & take_rows(dummy, pairs.index), coefficient, 0.0)
        rise = sum(o * g for o, g in zip(pairs.offset, params.gravity, strict=True))
        return params.density * jnp.sum(c * rise, axis=1)

    def tolerance(self, dtype) -> float:
        """The relative tolerance of the solve in `dtype`."""
        if self.rtol is not None:
            return self.rtol
        return DEFAULT_RTOL[jnp.dtype(dtype) == jnp.float64]

    def __call__(
        self,
        disc: Discretisation,
        laplacian: AbstractLaplacian,
        grid: Grid,
        params: Params,
        inputs: PressureInputs,
    ) -> PressureSolution:
        # With <lap p>_i = f sum_j c_ij (p_j - p_i) (the Scene's Laplacian),
        # A p = sum_j c_ij (p_i - p_j) = -<lap p> / f, so b = -S / f for <lap p> = S
        # (eq. 2.2-14/15).
        pairs, _ = inputs.source_pairs(inputs.pairs)
        pairs_k, n_k = inputs.source_pairs(inputs.pairs_k)
        sources = SourceInputs(
            pairs=pairs,
            n_star=inputs.n_star,
            u_star=self._source_velocity(params, inputs),
            pairs_k=pairs_k,
            n_k=n_k,
            velocity_k=inputs.velocity_k,
            density=params.density,
            dt=params.dt,
            reference_dt=inputs.reference_dt,
        )
        coefficient, factor = laplacian.coefficients(inputs.pairs, disc)
        if self.variable_density and inputs.coupling is not None:
            coefficient = _density_weighted(
                inputs.pairs.weight if coefficient is None else coefficient,
                inputs.pairs,
                inputs.coupling.density,
                params.density,
            )
        source = -self.source(disc, sources) / factor
        head = self._dummy_head(params, inputs, coefficient)
        if head is not None:
            source = source + head
        pressure, info = solve_pressure(
            inputs.pairs,
            inputs.kind,
            inputs.active,
            inputs.surface,
            source,
            inputs.pressure_k,
            self.tolerance(inputs.position.dtype),
            self.atol,
            self.max_iterations,
            coefficient,
            functools.partial(self.preconditioner, grid, disc, inputs.position),
            self._surface_pressure(disc, params, inputs),
        )
        if self.clamp_negative_pressure:
            pressure = jnp.maximum(pressure, 0.0)
        return PressureSolution(
            pressure=pressure,
            free=inputs.surface,
            iterations=info.iterations,
            residual=info.residual,
            converged=info.converged,
            unstable=jnp.asarray(False),
        )


def _density_weighted(
    coefficient: Float[Array, "n k"], pairs: Pairs, density, reference
) -> Float[Array, "n k"]:
    """The pair coefficients c_ij times rho0 / rho_ij, rho_ij = (rho_i + rho_j) / 2
    (symmetric, so the system stays symmetric positive definite)."""
    density = jnp.broadcast_to(density, pairs.index.shape[:1])
    mean = 0.5 * (density[:, None] + take_rows(density, pairs.index))
    return coefficient * (reference / mean)


def _facing_up(pairs: Pairs, carries: Mask, gravity) -> Field:
    """How far each particle's surface faces up, against gravity: max(0, n.up)
    with n the outward normal, minus the direction of sum_j w_ij r_ij over its
    pressure-carrying neighbours (1 on a flat top, 0 on a vertical face)."""
    w = jnp.where(pairs.valid & take_rows(carries, pairs.index), pairs.weight, 0.0)
    inward = [jnp.sum(w * o, axis=1) for o in pairs.offset]
    along = sum(m * g for m, g in zip(inward, gravity, strict=True))
    # |m| |g|, kept off 0 inside the root so that its gradient stays finite
    tiny = jnp.finfo(along.dtype).tiny
    scale = jnp.sqrt(sum(m**2 for m in inward) * jnp.sum(gravity**2) + tiny)
    return jnp.clip(along / scale, 0.0, 1.0)
