"""Weight functions of the MPS operators, and the reference constants n0 and lambda."""

import abc
import itertools

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float


class AbstractWeight(eqx.Module):
    """A radial weight w(r) with support r < r_e."""

    @abc.abstractmethod
    def value(self, r: np.ndarray | Array, r_e: float) -> np.ndarray | Array:
        """w(r) for 0 < r < r_e (callers mask r = 0 and r >= r_e themselves)."""

    @abc.abstractmethod
    def derivative(self, r: np.ndarray | Array, r_e: float) -> np.ndarray | Array:
        """dw/dr for 0 < r < r_e (the higher-order source and Laplacian use it)."""

    @abc.abstractmethod
    def second_derivative(
        self, r: np.ndarray | Array, r_e: float
    ) -> np.ndarray | Array:
        """d^2w/dr^2 for 0 < r < r_e."""

    def __call__(
        self, r: Float[Array, "*b"], valid: Bool[Array, "*b"], r_e: float
    ) -> Float[Array, "*b"]:
        """w(r), zero where `valid` is False or r >= r_e, with finite gradients.

        `r` must already be safe (not zero) where `valid` holds; see `safe_norm`.
        """
        inside = jnp.logical_and(valid, r < r_e)
        safe_r = jnp.where(inside, r, r_e)
        return jnp.where(inside, self.value(safe_r, r_e), 0.0)


class MPSWeight(AbstractWeight):
    """The standard MPS weight w(r) = r_e / r - 1 (Koshizuka & Oka 1996; seed 000
    eq. 2.1-3). Singular at r = 0, which is excluded (self and padded pairs)."""

    def value(self, r, r_e):
        return r_e / r - 1.0

    def derivative(self, r, r_e):
        return -r_e / r**2

    def second_derivative(self, r, r_e):
        return 2.0 * r_e / r**3


class EMPSWeight(AbstractWeight):
    """E-MPS weight of number density, Laplacian and divergence (Yamada et al. 2011;
    seed 002 eq. 3.5): w(r) = r_e/r + r/r_e - 2, zero value at r = r_e."""

    def value(self, r, r_e):
        return r_e / r + r / r_e - 2.0

    def derivative(self, r, r_e):
        return -r_e / r**2 + 1.0 / r_e

    def second_derivative(self, r, r_e):
        return 2.0 * r_e / r**3


class EMPSGradientWeight(AbstractWeight):
    """E-MPS weight of the pressure gradient (seed 002 eq. 3.6): r_e/r - r/r_e."""

    def value(self, r, r_e):
        return r_e / r - r / r_e

    def derivative(self, r, r_e):
        return -r_e / r**2 - 1.0 / r_e

    def second_derivative(self, r, r_e):
        return 2.0 * r_e / r**3


class WendlandWeight(AbstractWeight):
    """Wendland (1995) C2 weight w(r) = (1 - r/r_e)^4 (1 + 4 r/r_e) (seed 001 eq.
    2.31), the kernel of the high-accuracy scheme. Finite at r = 0 (w = 1) with a
    gentle slope; w' and w'' vanish continuously at r_e."""

    def value(self, r, r_e):
        q = r / r_e
        return (1.0 - q) ** 4 * (1.0 + 4.0 * q)

    def derivative(self, r, r_e):
        q = r / r_e
        return -20.0 * r / r_e**2 * (1.0 - q) ** 3

    def second_derivative(self, r, r_e):
        q = r / r_e
        return 20.0 / r_e**2 * (1.0 - q) ** 2 * (4.0 * q - 1.0)


def lattice_offsets(dim: int, r_e: float) -> np.ndarray:
    """Offsets of a unit square/cubic lattice point's neighbours with 0 < |x| < r_e
    (in units of the spacing)."""
    reach = int(np.ceil(r_e))
    grid = itertools.product(range(-reach, reach + 1), repeat=dim)
    pts = np.array([p for p in grid if p != (0,) * dim], dtype=np.float64)
    r = np.linalg.norm(pts, axis=1)
    return pts[r < r_e]


def lattice_sum(fn, dim: int, r_e_over_l0: float) -> float:
    """sum_j fn(|r_ij|, r_ij) over the neighbours of an interior point of the unit
    lattice (spacing 1, radius `r_e_over_l0`): the reference value of a pair sum,
    e.g. for normalising an operator so that it is exact on the initial lattice."""
    offsets = lattice_offsets(dim, r_e_over_l0)
    r = np.linalg.norm(offsets, axis=1)
    return float(np.sum(np.asarray(fn(r, offsets), dtype=np.float64)))


def reference_constants(
    weight: AbstractWeight, dim: int, r_e_over_l0: float
) -> tuple[float, float]:
    """n0 and lambda (in units of l0^2) of an interior particle of a regular lattice.

    n0 = sum_j w(|r_ij|) (eq. 2.1-4) and lambda = sum_j |r_ij|^2 w / sum_j w
    (eq. 2.1-7), both over the full neighbourhood of a lattice point with spacing 1.
    """
    offsets = lattice_offsets(dim, r_e_over_l0)
    r = np.linalg.norm(offsets, axis=1)
    w = np.asarray(weight.value(r, r_e_over_l0), dtype=np.float64)
    n0 = float(np.sum(w))
    lam = float(np.sum(r**2 * w) / n0)
    return n0, lam
