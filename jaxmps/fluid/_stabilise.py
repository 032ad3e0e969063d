"""Dynamic stabilisation (DS) of Tsuruta, Khayyer & Gotoh (2013), seed 001 §2.3.3."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._numerics import (
    component_dot,
    pair_differences,
    pair_sum,
    safe_norm,
    take_rows,
)
from .._types import Kind, Kinds, Mask
from ..operators import Discretisation, Pairs


class DynamicStabilisation(eqx.Module):
    """The least repulsion that keeps particle pairs apart (seed 001 eq. 2.26-2.30).

    After the pressure correction, the positions r** it would give are predicted.
    A pair with |r**_ij| < d_ij = alpha l0 gets the acceleration that restores it to
    point contact along e_ij = r^k_ij / |r^k_ij|:
        Pi_ij = m_j / (dt^2 (m_i + m_j)) (sqrt(d_ij^2 - |r**_perp|^2) - r**_par),
    and particle i is pushed away from j by Pi_ij (times w_ij / n0 when
    `weighted`). r**_par is the signed projection on e_ij, so crossed pairs are
    pushed back through (digest §3.5 caution 4).

    Attributes:
        alpha: contact distance in units of l0 (1 - Courant limit; 0.9 in seed 001).
        weighted: scale each pair correction by w_ij / n0 as printed (eq. 2.30);
            False applies the full pair correction.
    """

    # Choice (digest §3.5 cautions 1 and 3): the printed force attracts under the
    # r_ij = r_j - r_i convention of the gradient; we apply it as repulsion. Only
    # fluid particles are corrected; a partner that is not fluid (wall, dummy,
    # body) does not move in this stage, so the fluid particle takes the whole
    # correction (mass ratio 1 instead of 1/2). Fluid-fluid pairs share it equally
    # (one fluid density), which keeps their momentum.
    alpha: float = 0.9
    weighted: bool = True

    def __check_init__(self):
        if not 0 < self.alpha <= 1:
            raise ValueError(
                f"DynamicStabilisation.alpha must lie in (0, 1], got {self.alpha}."
            )

    def __call__(
        self,
        disc: Discretisation,
        pairs: Pairs,
        position_k: Float[Array, "n d"],
        predicted: Float[Array, "n d"],
        kind: Kinds,
        active: Mask,
        dt: Float[Array, ""],
    ) -> Float[Array, "n d"]:
        """Acceleration of each particle [m/s^2] (zero for all but fluid)."""
        fluid = jnp.logical_and(active, kind == int(Kind.FLUID))
        listed = pairs.valid
        index = pairs.index
        offset_k = pair_differences(position_k, index)
        r_k = safe_norm(offset_k, listed, placeholder=1.0)
        e = tuple(jnp.where(listed, o / r_k, 0.0) for o in offset_k)
        offset = pair_differences(predicted, index)
        parallel = component_dot(offset, e)
        r2 = component_dot(offset, offset)
        contact = self.alpha * disc.spacing
        close = listed & (r2 < contact**2) & fluid[:, None]
        perp2 = jnp.maximum(r2 - parallel**2, 0.0)
        gap = jnp.sqrt(jnp.where(close, contact**2 - perp2, 1.0)) - parallel
        share = jnp.where(take_rows(fluid, index), 0.5, 1.0)
        pi = jnp.where(close, share * gap / dt**2, 0.0)
        if self.weighted:
            pi = pi * pairs.weight / disc.n0
        return -pair_sum(pi, e)
