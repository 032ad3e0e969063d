"""Adaptive time steps: their settings (the limits: `_step.time_step_limits`)."""

import math

import equinox as eqx
import jax.numpy as jnp

from . import fluid
from ._params import Params
from ._types import Scalar

# Choice: the default Courant numbers of adaptive steps (`Adaptive.courant`):
# with the semi-implicit solver's dynamic stabilisation, and otherwise (measured
# in `benchmarks/NOTES.md` §17).
STABILISED_COURANT = 0.2
COURANT = 0.1


class Adaptive(eqx.Module):
    """Choose every step's dt from the state (`Scene.time_step`).

    A step takes the smallest of these limits, each a safety factor times a
    stability or accuracy bound, and never more than `Params.dt` (which, under
    adaptive stepping, is the largest step `dt_max`):

        courant    courant l0 / max|u|           (mobile particles, start of step)
        force      force sqrt(l0 / max|a|)       (max|a| by forces in the last
                                                 step: gravity, viscosity, and
                                                 the explicit solver's pressure)
        viscous    stability x viscous_limit lambda / (2 d nu)
        solver     stability x the pressure stage's limit (explicit: sound_courant
                   l0 / c; semi-implicit: none)
        <body>     stability x each body model's limit (rigid bodies: none)

    A step that still exceeds a stability limit or ends non-finite (a velocity
    that jumped within one step, an impact) is taken again with half the dt; a dt
    below `dt_min` ends the run with `Result.time_step_below_minimum`.

    The dt is a constant to the gradient (`jax.lax.stop_gradient`): see
    `jaxmps.time_step`.

    Attributes:
        courant: Courant number of the step on the flow's largest speed; None
            (the default): `STABILISED_COURANT` (0.2, the step seeds 000 and
            001 take) for the semi-implicit solver with dynamic stabilisation
            (`scheme=standard_ds`, `high_accuracy`), `COURANT` (0.1) otherwise.
            The default scheme's collision guard acts on the start-of-step
            positions, so a longer step lets particles meet inside it: a
            semi-implicit dam break of a 0.6 m x 0.3 m column at l0 = 1 cm blew
            up after its impacts at 0.2 (velocities of 80 m/s at 1.19 s; in
            float64 `time_step_below_minimum` at 1.40 s in one measurement, 29
            steps taken again in another, and the doubled column stopped at
            1.51 s) and ran to 2 s at 0.1 and 0.05
            (`benchmarks/adaptive_steps.py`). Dynamic stabilisation separates
            the particles at their predicted positions; with it the same
            column, halved and doubled, runs to 2 s at 0.2 with no step taken
            again, and the surge front is that of 0.1 to 1 %
            (`benchmarks/NOTES.md` §17).
        force: factor of the force limit (0.25, the usual SPH value, e.g.
            Monaghan 1992).
        stability: fraction of the hard stability limits (`Scene.viscous_limit`,
            the explicit solver's `sound_courant`) a step may use; 0.5 gives the
            explicit solver c dt / l0 = 0.4, the value seed 002 runs at.
        dt_min: the smallest step [s] before the run is given up; None: 1e-2 x
            `Params.dt` (a flow 50 times faster than the scene's velocity scale
            at Courant 0.1, or seven halvings of a rejected step: an
            instability, not a flow to follow).
    """

    courant: float | None = None
    force: float = 0.25
    stability: float = 0.5
    dt_min: float | None = None

    def __check_init__(self):
        for name in ("courant", "force", "stability"):
            value = getattr(self, name)
            if name == "courant" and value is None:
                continue
            if not (isinstance(value, (int, float)) and 0 < value <= 1):
                raise ValueError(f"Adaptive.{name} must be in (0, 1], got {value!r}.")
        if self.dt_min is not None and not (
            math.isfinite(self.dt_min) and self.dt_min > 0
        ):
            raise ValueError(
                f"Adaptive.dt_min must be positive and finite [s], got {self.dt_min!r}."
            )

    def courant_for(self, scene) -> float:
        """The Courant number of `scene`'s steps: `courant`, or where None the
        default for its scheme (`STABILISED_COURANT` where the semi-implicit
        projection has dynamic stabilisation, else `COURANT`)."""
        if self.courant is not None:
            return self.courant
        stabilised = isinstance(scene.solver, fluid.SemiImplicit) and isinstance(
            scene.stabiliser, fluid.DynamicStabilisation
        )
        return STABILISED_COURANT if stabilised else COURANT

    def smallest(self, params: Params) -> Scalar:
        """The smallest step a run may take [s]."""
        if self.dt_min is None:
            return 1e-2 * params.dt
        return jnp.asarray(self.dt_min, params.dt.dtype)
