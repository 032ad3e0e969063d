"""The pressure stage: what distinguishes the semi-implicit and explicit solvers."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._coupling import Coupling, source_view
from .._params import Params
from .._types import Field, Kinds, Mask, Scalar, Velocities
from ..neighbours import Grid
from ..operators import AbstractLaplacian, Discretisation, Pairs


class PressureInputs(eqx.Module):
    """What a pressure stage may use.

    Attributes:
        pairs: pair geometry at the tentative positions r*.
        n_star: particle number density at r*.
        position: the tentative positions r* [m].
        velocity: the tentative velocities u* [m/s].
        surface: free-surface flags at r* (all False without a surface model).
        pairs_k: pair geometry at the start of the step (r^k).
        velocity_k: velocities at the start of the step u^k [m/s].
        pressure_k: the pressures of the previous step [Pa] (a warm start).
        kind, active: the particles' kinds and active flags.
        reference_dt: the step a per-step relaxation is meant for [s]:
            `Params.relaxation_step` (the scenes' calm step for their resolution),
            or where that is None `Params.dt`, the step itself with fixed steps
            and the largest step (`dt_max`) with adaptive ones (see
            `MixedSource`); None: the step itself.
        coupling: what the bodies impose (None without bodies); a source sees
            the pairs of `Coupling.source_view` (`n_star` is already of it).
    """

    pairs: Pairs
    n_star: Field
    position: Float[Array, "n d"]
    velocity: Velocities
    surface: Mask
    pairs_k: Pairs
    velocity_k: Velocities
    pressure_k: Field
    kind: Kinds
    active: Mask
    reference_dt: Scalar | None = None
    coupling: Coupling | None = None

    def source_pairs(self, pairs: Pairs) -> tuple[Pairs, Field]:
        """`pairs` and their number density as a source sees them
        (`Coupling.source_view`)."""
        return source_view(self.coupling, pairs)


class PressureSolution(eqx.Module):
    """The pressure of a step and the stage's diagnostics.

    Attributes:
        pressure: pressure of every particle [Pa] (0 on the free surface).
        free: particles held at zero pressure as free surface.
        iterations: linear-solver iterations (0 for the explicit stage).
        residual: final relative residual of the linear solve (0 if none).
        converged: whether the solve reached its tolerance (True if none).
        unstable: a stage-specific stability limit was exceeded this step.
    """

    pressure: Field
    free: Mask
    iterations: Int[Array, ""]
    residual: Float[Array, ""]
    converged: Bool[Array, ""]
    unstable: Bool[Array, ""]


class AbstractPressureSolver(eqx.Module):
    """How the pressure of a step is found: a pressure Poisson equation
    (`SemiImplicit`) or an equation of state (`Explicit`). Every other stage of a
    step is shared by both (`jaxmps.step`).

    Attributes:
        needs_surface: whether the stage needs free-surface flags (a Scene with
            this solver must have a `FreeSurface` model).
        pressure_is_force: whether the pressure acts as a force of the state (an
            equation of state), so that its acceleration bounds the step like
            gravity's; False for a projection, whose correction of the velocity
            grows as 1/dt and would shorten each step further than the last
            (`jaxmps.Adaptive`, the force limit).
    """

    needs_surface: eqx.AbstractClassVar[bool]
    pressure_is_force: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def __call__(
        self,
        disc: Discretisation,
        laplacian: AbstractLaplacian,
        grid: Grid,
        params: Params,
        inputs: PressureInputs,
    ) -> PressureSolution:
        """The pressure at r*."""

    def time_step_limit(self, disc: Discretisation, params: Params) -> Scalar:
        """The largest dt this stage is stable at [s] (inf: no limit of its own);
        adaptive steps take a fraction of it (`jaxmps.Adaptive.stability`)."""
        del disc
        return jnp.asarray(jnp.inf, params.dt.dtype)

    def check_params(self, disc: Discretisation, params: Params) -> None:
        """Refuse, before any tracing, Params this solver cannot run (ValueError).

        Only concrete values are checked; traced ones (inside jit or vmap) are left
        to the run-time result codes.
        """
        del disc, params
