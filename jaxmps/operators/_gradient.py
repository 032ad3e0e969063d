"""MPS gradients: standard (eq. 2.1-5), corrected (Iribe & Nakaza, eq. 2.3-9) and
the symmetric pair form (E-MPS, eq. 3.33 of seed 002; bodies)."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._numerics import pair_sum, small_determinant, small_inverse, take_rows
from ._discretisation import Discretisation
from ._pairs import Pairs
from ._weight import AbstractWeight, reference_constants


class AbstractGradient(eqx.Module):
    """Gradient of a scalar field from the values at neighbours."""

    @abc.abstractmethod
    def __call__(
        self,
        pairs: Pairs,
        field: Float[Array, " n"],
        disc: Discretisation,
        include: Bool[Array, "n k"],
        select: Bool[Array, "n k"] | None = None,
    ) -> Float[Array, "n d"]:
        """<grad phi>_i over the neighbours j where `include` holds.

        With `select`, only the terms of the selected pairs are summed (the operator
        itself, i.e. moment matrix and minimum, still comes from `include`): the part
        of the gradient those neighbours contribute. Used to split contact forces.
        """

    def momentum_conserving(self) -> "SymmetricGradient":
        """The form of this gradient whose pair forces are equal and opposite, for
        particles whose forces are summed into a body: the symmetric pair form
        with the discretisation's weight, unless this gradient is one already."""
        return SymmetricGradient()


def _select(w, select):
    return w if select is None else jnp.where(select, w, 0.0)


def _masked(pairs: Pairs, field, include):
    """Weights w_ij of the included pairs (0 elsewhere) and phi_j - phi_i."""
    mask = jnp.logical_and(pairs.valid, include)
    w = jnp.where(mask, pairs.weight, 0.0)
    diff = take_rows(field, pairs.index) - field[:, None]
    return w, diff


class StandardGradient(AbstractGradient):
    """<grad phi>_i = d/n0 sum_j (phi_j - phi_i) r_ij / |r_ij|^2 w_ij (eq. 2.1-5).

    Exact for linear fields only on a full regular lattice neighbourhood.
    """

    def __call__(
        self,
        pairs: Pairs,
        field: Float[Array, " n"],
        disc: Discretisation,
        include: Bool[Array, "n k"],
        select: Bool[Array, "n k"] | None = None,
    ) -> Float[Array, "n d"]:
        w, diff = _masked(pairs, field, include)
        w = _select(w, select)
        return (disc.dim / disc.n0) * pair_sum(
            diff * w / pairs.distance**2, pairs.offset
        )


class MinimumPressureGradient(AbstractGradient):
    """Koshizuka's stabilised gradient (seed 000 eq. 2.2-16/17):
    <grad phi>_i = d/n0 sum_j (phi_j - phihat_i) r_ij / |r_ij|^2 w_ij, with
    phihat_i = min(phi_i, min_j phi_j) over the included neighbours.

    Always repulsive for a pressure field, which suppresses tensile clustering, at the
    cost of first-order consistency (a uniform offset is no longer ignored exactly).
    """

    def __call__(
        self,
        pairs: Pairs,
        field: Float[Array, " n"],
        disc: Discretisation,
        include: Bool[Array, "n k"],
        select: Bool[Array, "n k"] | None = None,
    ) -> Float[Array, "n d"]:
        mask = jnp.logical_and(pairs.valid, include)
        phi_j = take_rows(field, pairs.index)
        phi_min = jnp.min(jnp.where(mask, phi_j, jnp.inf), axis=1)
        phi_hat = jnp.minimum(field, phi_min)
        w = _select(jnp.where(mask, pairs.weight, 0.0), select)
        coefficient = (phi_j - phi_hat[:, None]) * w / pairs.distance**2
        return (disc.dim / disc.n0) * pair_sum(coefficient, pairs.offset)


class CorrectedGradient(AbstractGradient):
    """Tensor-corrected gradient of Iribe & Nakaza (2010, 2011), seed 000 eq. 2.3-9.

    C_i = [1/n0 sum_j w_ij e_ij (x) e_ij]^-1 and
    <grad phi>_i = C_i 1/n0 sum_j w_ij (phi_j - phi_i) / |r_ij| e_ij.
    Exact for linear fields on any non-degenerate neighbourhood; no minimum-pressure
    substitution (seed 000 §2.8).

    Attributes:
        min_det: the moment matrix is treated as singular when its determinant falls
            below `min_det` times that of the isotropic lattice value (1/d) I.
        minimum_shift: use phi_j - phihat_i with phihat_i = min(phi_i, min_j phi_j)
            (Koshizuka's stabilisation, eq. 2.2-17) inside the corrected operator.
    """

    # Choice: the seed gives no fallback for singular moment matrices (splash
    # particles, one-sided or collinear neighbourhoods). We fall back to the standard
    # gradient (C = d I, its isotropic value) when det(M) < min_det * d^-d; this keeps
    # the operator bounded and reduces to the seed's own formula for isotropic sets.
    min_det: float = 0.05
    # Choice: seed 000 uses the corrected gradient *without* the minimum-pressure
    # shift. In our hydrostatic tanks that form is unstable at the contact line (free
    # surface meeting a wall): spurious speeds grow from the top corners and the run
    # explodes within 0.3-0.5 s for every source term, tolerance and precision we
    # tried. With the shift, max spurious speed stays below ~0.1 m/s (0.2 m tank,
    # l0 = 0.01 m). The default scheme (`schemes.standard`) therefore uses
    # `CorrectedGradient(minimum_shift=True)`; this class's default,
    # `CorrectedGradient()`, is the operator as the seed defines it (exact on linear
    # fields, which the shifted form is not), which `schemes.high_accuracy` and
    # `schemes.standard(dynamic_stabilisation=True)` use: with dynamic
    # stabilisation in place of the collision guard it is stable, and the shift's
    # spurious repulsion no longer shortens the period of waves.
    minimum_shift: bool = False

    def __call__(
        self,
        pairs: Pairs,
        field: Float[Array, " n"],
        disc: Discretisation,
        include: Bool[Array, "n k"],
        select: Bool[Array, "n k"] | None = None,
    ) -> Float[Array, "n d"]:
        n0, dim = disc.n0, disc.dim
        w, diff = _masked(pairs, field, include)
        if self.minimum_shift:
            mask = jnp.logical_and(pairs.valid, include)
            phi_j = take_rows(field, pairs.index)
            phi_min = jnp.min(jnp.where(mask, phi_j, jnp.inf), axis=1)
            diff = phi_j - jnp.minimum(field, phi_min)[:, None]
        # M = 1/n0 sum_j w_ij e_ij (x) e_ij, one symmetric entry at a time.
        w_r2 = w / pairs.distance**2 / n0
        o = pairs.offset
        entries = {
            (a, b): jnp.sum(w_r2 * o[a] * o[b], axis=1)
            for a in range(dim)
            for b in range(a, dim)
        }
        moment = jnp.stack(
            [
                jnp.stack([entries[min(a, b), max(a, b)] for b in range(dim)], -1)
                for a in range(dim)
            ],
            -2,
        )
        det = small_determinant(moment)
        ok = det > self.min_det * float(dim) ** (-dim)
        isotropic = jnp.eye(dim, dtype=moment.dtype) / dim
        safe_moment = jnp.where(ok[:, None, None], moment, isotropic)
        correction = small_inverse(
            safe_moment, jnp.where(ok, det, float(dim) ** (-dim))
        )
        w = _select(w, select)
        rhs = pair_sum(diff * w / pairs.distance**2, pairs.offset) / n0
        return jnp.stack(
            [
                sum(correction[:, a, b] * rhs[:, b] for b in range(dim))
                for a in range(dim)
            ],
            -1,
        )


class SymmetricGradient(AbstractGradient):
    """The symmetric pair form
    <grad phi>_i = d/n0_w sum_j (phi_i + phi_j) r_ij / |r_ij|^2 w(|r_ij|),
    whose pair terms are equal and opposite, so that summed over a body the forces
    of its internal pairs cancel and the net force is exactly that of the pairs
    across its surface (action equals reaction pair by pair).

    With `weight`, its own kernel and n0_w (the E-MPS gradient of seed 002 eq. 3.33
    with `EMPSGradientWeight()`); without, the discretisation's weight and n0.

    Attributes:
        weight: the kernel of this gradient, or None for the discretisation's.
    """

    weight: AbstractWeight | None = None

    def momentum_conserving(self) -> "SymmetricGradient":
        return self

    def __call__(
        self,
        pairs: Pairs,
        field: Float[Array, " n"],
        disc: Discretisation,
        include: Bool[Array, "n k"],
        select: Bool[Array, "n k"] | None = None,
    ) -> Float[Array, "n d"]:
        mask = jnp.logical_and(pairs.valid, include)
        if self.weight is None:
            w, n0 = jnp.where(mask, pairs.weight, 0.0), disc.n0
        else:
            w = self.weight(pairs.distance, mask, disc.r_e)
            n0, _ = reference_constants(self.weight, disc.dim, disc.r_e / disc.spacing)
        w = _select(w, select)
        total = take_rows(field, pairs.index) + field[:, None]
        return (disc.dim / n0) * pair_sum(total * w / pairs.distance**2, pairs.offset)
