"""Pressure Poisson equation of the semi-implicit step (seed 000 eq. 2.2-14/15)."""

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._numerics import take_rows
from .._types import PRESSURE_KINDS, is_kind
from ..operators import Pairs
from ._cg import SolveInfo, solve_spd


def pressure_system(
    pairs: Pairs,
    kind,
    active: Bool[Array, " n"],
    surface: Bool[Array, " n"],
    coefficient: Float[Array, "n k"] | None = None,
):
    """The PPE operator A (symmetric positive definite), its diagonal and row mask.

    For a particle i in the system S (active fluid/wall/body, not on the surface):
        (A p)_i = sum_j c_ij (p_i - [j in S] p_j),
    with c_ij the Laplacian's pair coefficient (default w_ij, the standard
    Laplacian) for pressure-carrying neighbours j. Surface neighbours have
    p_j = 0 (Dirichlet) and stay in the diagonal; dummy neighbours drop out of both
    the diagonal and the off-diagonal terms (a zero-gradient Neumann wall, seed 000
    §2.4.2). Rows outside S are the identity, so their pressure solves to 0.
    """
    carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    in_system = jnp.logical_and(carries, ~surface)
    c = pairs.weight if coefficient is None else coefficient
    coupling = jnp.where(pairs.valid & take_rows(carries, pairs.index), c, 0.0)
    diag = jnp.sum(coupling, axis=1)
    neighbour_in_system = take_rows(in_system, pairs.index)
    off = jnp.where(neighbour_in_system, coupling, 0.0)

    def matvec(p):
        row = diag * p - jnp.sum(off * take_rows(p, pairs.index), axis=1)
        return jnp.where(in_system, row, p)

    # A row in S with no pressure-carrying neighbour cannot occur for beta < 1 (its
    # number density would flag it as surface); guard the preconditioner anyway.
    safe_diag = jnp.where(in_system & (diag > 0), diag, 1.0)
    return matvec, safe_diag, in_system


def solve_pressure(
    pairs: Pairs,
    kind,
    active: Bool[Array, " n"],
    surface: Bool[Array, " n"],
    source: Float[Array, " n"],
    guess: Float[Array, " n"],
    rtol: float,
    atol: float,
    max_iterations: int,
    coefficient: Float[Array, "n k"] | None = None,
) -> tuple[Float[Array, " n"], SolveInfo]:
    """Solve A p = source on the system rows (source is ignored elsewhere)."""
    matvec, diag, in_system = pressure_system(pairs, kind, active, surface, coefficient)
    b = jnp.where(in_system, source, 0.0)
    x0 = jnp.where(in_system, guess, 0.0)
    return solve_spd(matvec, b, x0, 1.0 / diag, rtol, atol, max_iterations)
