"""Source terms of the pressure Poisson equation (strategies)."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import component_dot, pair_differences
from ..operators import Discretisation, Pairs, lattice_sum


class SourceInputs(eqx.Module):
    """What a PPE source may use.

    Attributes:
        pairs, n_star, u_star: pair geometry, number density and velocity at the
            tentative positions r* (after the explicit stage).
        pairs_k, n_k, velocity_k: the same at the start of the step (r^k, u^k).
        density: reference density rho0 [kg/m^3].
        dt: time step [s].
        reference_dt: the step a per-step density relaxation is meant for [s]
            (`PressureInputs.reference_dt`); None: `dt` (fixed steps).
    """

    pairs: Pairs
    n_star: Float[Array, " n"]
    u_star: Float[Array, "n d"]
    pairs_k: Pairs
    n_k: Float[Array, " n"]
    velocity_k: Float[Array, "n d"]
    density: Float[Array, ""]
    dt: Float[Array, ""]
    reference_dt: Float[Array, ""] | None = None


class AbstractSource(eqx.Module):
    """Right-hand side S of the PPE  <lap P>_i = S_i  [Pa/m^2]."""

    @abc.abstractmethod
    def __call__(
        self, disc: Discretisation, inputs: SourceInputs
    ) -> Float[Array, " n"]:
        """S_i [Pa/m^2]."""


# Choice: a density term restores a fraction (its relaxation) of the density error
# per *reference* step, rho0/(dt dt_ref) (n0 - n)/n0, not per step, rho0/dt^2 ...
# as printed. The two agree with fixed steps (dt = dt_ref). With adaptive steps the
# printed form restores the error faster the shorter the step, and the velocity it
# imposes, relaxation x l0 x error / dt, grows as the step shrinks: at an impact
# that feeds back (faster particles, a shorter step, a stronger kick) until the
# step falls below dt_min (the 2x Lobovsky dam break, benchmarks/NOTES.md). Per
# reference step, the restoring rate per second and the imposed velocity do not
# depend on the step.
def _density_term(inputs: SourceInputs, n, n0):
    """rho0/(dt dt_ref) (n0 - n)/n0."""
    reference = inputs.dt if inputs.reference_dt is None else inputs.reference_dt
    return inputs.density / (inputs.dt * reference) * (n0 - n) / n0


class DensitySource(AbstractSource):
    """Seed 000 eq. 2.2-14: S = relaxation * rho0/dt^2 (n0 - n*)/n0 (one dt of the
    two is the reference step with adaptive steps: see `_density_term`).

    With relaxation = 1 and fixed steps this is the source as printed. It corrects
    positions but leaves the pressure impulse in the velocity, so a density error e
    and its rate y = dt div(u) obey e' = (1 - a)(e + y), y' = (1 - a) y - a e
    (a = relaxation x the discrete operator gain g, measured 1.34-1.40 on a
    lattice): stable only for a < 4/3, and undamped in y, so spurious currents grow
    like 1/dt. Kept for reproducing the seed; `MixedSource` is the default.
    """

    relaxation: float = 1.0

    def __call__(
        self, disc: Discretisation, inputs: SourceInputs
    ) -> Float[Array, " n"]:
        return self.relaxation * _density_term(inputs, inputs.n_star, disc.n0)


class MixedSource(AbstractSource):
    """Tanaka & Masunaga (2010, J. Comput. Phys. 229:4279) mixed source:
    S = rho0/dt div(u*) + gamma rho0/(dt dt_ref) (n0 - n*)/n0,
    with the MPS divergence div(u)_i = d/n0 sum_j (u_j - u_i).r_ij/|r_ij|^2 w_ij.

    The divergence term removes the velocity memory of the density source (the
    corrected velocity is discretely divergence-free) and the small density term
    keeps the particle number density from drifting. With fixed steps dt_ref = dt
    (as printed); with adaptive steps it is the largest step, `Params.dt`, so that
    gamma is a relaxation per largest step whatever the step (`_density_term`).
    """

    gamma: float = 0.01

    def __call__(
        self, disc: Discretisation, inputs: SourceInputs
    ) -> Float[Array, " n"]:
        pairs, u = inputs.pairs, inputs.u_star
        du = pair_differences(u, pairs.index)
        radial = component_dot(du, pairs.offset) / pairs.distance**2
        divergence = (disc.dim / disc.n0) * jnp.sum(radial * pairs.weight, axis=1)
        return inputs.density / inputs.dt * divergence + self.gamma * _density_term(
            inputs, inputs.n_star, disc.n0
        )


def density_rate(
    disc: Discretisation, pairs: Pairs, velocity: Float[Array, "n d"]
) -> Float[Array, " n"]:
    """Dn_i/Dt = sum_j w'(r_ij) (r_ij . u_ij) / r_ij, the exact time derivative of
    the number density for the current velocities (seed 001 eq. 2.3)."""
    safe_r = jnp.where(pairs.valid, pairs.distance, disc.r_e)
    slope = jnp.where(pairs.valid, disc.weight.derivative(safe_r, disc.r_e), 0.0)
    du = pair_differences(velocity, pairs.index)
    closing = component_dot(du, pairs.offset) / pairs.distance
    return jnp.sum(slope * closing, axis=1)


class AbstractCompensation(eqx.Module):
    """An error-compensating term S_ECS subtracted from the PPE source (x rho0)."""

    @abc.abstractmethod
    def __call__(
        self, disc: Discretisation, inputs: SourceInputs
    ) -> Float[Array, " n"]:
        """S_ECS_i [1/s^2]."""


class DynamicCompensation(AbstractCompensation):
    """Dynamic error-compensating source (ECS) of Khayyer & Gotoh (2011), seed 001
    eq. 2.8 with the factor rho0 (digest erratum 4):
    S_ECS = |e|/dt (1/n0) Dn^k/Dt + |(1/n0) Dn^k/Dt|/dt e,  e = (n^k - n0)/n0,
    with Dn^k/Dt the analytic rate at step k (`density_rate`). Its coefficients
    follow the instantaneous error, so it needs no tuning.
    """

    def __call__(
        self, disc: Discretisation, inputs: SourceInputs
    ) -> Float[Array, " n"]:
        n0 = disc.n0
        error = (inputs.n_k - n0) / n0
        rate = density_rate(disc, inputs.pairs_k, inputs.velocity_k) / n0
        return (jnp.abs(error) * rate + jnp.abs(rate) * error) / inputs.dt


class HigherOrderSource(AbstractSource):
    """Higher-order source (HS) of Khayyer & Gotoh (2009), seed 001 eq. 2.4-2.5:
    S = -(rho0 s / (n0 dt)) sum_j w'(r*_ij) (r*_ij . u*_ij) / r*_ij
        + gamma rho0/(dt dt_ref) (n0 - n^k)/n0  -  rho0 S_ECS,
    i.e. rho0/dt times minus the relative rate of change of the number density
    (with the sign of digest erratum 3), a Tanaka-Masunaga number-density term on
    n^k (eq. 2.5; dt_ref = dt with fixed steps, see `_density_term`) and an
    optional error-compensating term (ECS).

    Attributes:
        gamma: relaxation coefficient of the number-density term, a fraction of
            the density error restored per (reference) step. Seed 001 prints 1e-3,
            run there at dt = 2.5e-4 s; our default steps are 4-8 times longer
            (the Courant rule), which makes the same gamma 4-8 times weaker per
            second. Measured with the full scheme (validation/conservation.py, l0
            = 1 cm, dt = 1 ms, 2 s): gamma = 1e-3 lets the fluid compress by 3 %
            (hydrostatic) to 7 % (standing wave) with the level sinking 4-7 mm;
            0.01 gives 0.15-1 %; 0.02 (the default) within 0.06 % and 0.4 mm;
            0.05 within 0.1 %. In still water at
            the default steps (validation/still_water_noise.py: four tanks at 2
            cm, three at 1 cm) 1e-3 left the bottom pressure up to 6 times
            noisier than the `standard` preset in the small tanks; 0.02 (the
            default) is quieter than `standard` in every one (0.04-0.82 of its
            noise), and the standing wave's period stays within 2 % (-1.1 %;
            0.03 took it to -2.5 %).
        compensation: `DynamicCompensation()` (ECS) or None.
        normalised: s = -d n0 / sum_lattice w'(r) r, which makes the first term
            rho0/dt times an exact divergence of linear fields on the reference
            lattice; otherwise (default) s = 1 as printed (see the choice in
            `HigherOrderLaplacian`).
    """

    gamma: float = 0.02
    compensation: AbstractCompensation | None = DynamicCompensation()
    normalised: bool = False

    def __check_init__(self):
        if not 0 <= self.gamma < 1:
            raise ValueError(
                f"HigherOrderSource.gamma must lie in [0, 1) (a fraction of the "
                f"density error restored per step), got {self.gamma}; "
                "`schemes.high_accuracy(gamma=...)` sets it."
            )

    def scale(self, disc: Discretisation) -> float:
        if not self.normalised:
            return 1.0
        ratio = disc.r_e / disc.spacing
        moment = lattice_sum(
            lambda r, o: disc.weight.derivative(r, ratio) * r, disc.dim, ratio
        )
        return -disc.dim * disc.n0 / moment

    def __call__(
        self, disc: Discretisation, inputs: SourceInputs
    ) -> Float[Array, " n"]:
        n0 = disc.n0
        rate = density_rate(disc, inputs.pairs, inputs.u_star)
        source = -(inputs.density * self.scale(disc) / (n0 * inputs.dt)) * rate
        source = source + self.gamma * _density_term(inputs, inputs.n_k, n0)
        if self.compensation is not None:
            source = source - inputs.density * self.compensation(disc, inputs)
        return source
