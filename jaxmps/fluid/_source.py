"""Source terms of the pressure Poisson equation (strategies)."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import take_rows
from ..operators import Pairs


class AbstractSource(eqx.Module):
    """Right-hand side S of the PPE  <lap P>_i = S_i  (before rescaling to A p = b)."""

    @abc.abstractmethod
    def __call__(
        self,
        pairs: Pairs,
        n_star: Float[Array, " n"],
        u_star: Float[Array, "n d"],
        density: Float[Array, ""],
        dt: Float[Array, ""],
        n0: float,
        dim: int,
    ) -> Float[Array, " n"]:
        """S_i [Pa/m^2]."""


class DensitySource(AbstractSource):
    """Seed 000 eq. 2.2-14: S = relaxation * rho0/dt^2 (n0 - n*)/n0.

    With relaxation = 1 this is the source as printed. It corrects positions but leaves
    the pressure impulse in the velocity, so a density error e and its rate
    y = dt div(u) obey e' = (1 - a)(e + y), y' = (1 - a) y - a e (a = relaxation x
    the discrete operator gain g, measured 1.34-1.40 on a lattice): stable only for
    a < 4/3, and undamped in y, so spurious currents grow like 1/dt. Kept for
    reproducing the seed; `MixedSource` is the default.
    """

    relaxation: float = 1.0

    def __call__(self, pairs, n_star, u_star, density, dt, n0, dim):
        del pairs, u_star, dim
        return self.relaxation * density / dt**2 * (n0 - n_star) / n0


class MixedSource(AbstractSource):
    """Tanaka & Masunaga (2010, J. Comput. Phys. 229:4279) mixed source:
    S = rho0/dt div(u*) + gamma rho0/dt^2 (n0 - n*)/n0,
    with the MPS divergence div(u)_i = d/n0 sum_j (u_j - u_i).r_ij/|r_ij|^2 w_ij.

    The divergence term removes the velocity memory of the density source (the
    corrected velocity is discretely divergence-free) and the small density term
    keeps the particle number density from drifting.
    """

    gamma: float = 0.01

    def __call__(self, pairs, n_star, u_star, density, dt, n0, dim):
        du = take_rows(u_star, pairs.index) - u_star[:, None, :]
        radial = jnp.sum(du * pairs.offset, axis=-1) / pairs.distance**2
        divergence = (dim / n0) * jnp.sum(radial * pairs.weight, axis=1)
        return (
            density / dt * divergence
            + self.gamma * density / dt**2 * (n0 - n_star) / n0
        )
