"""Pressure Poisson equation of the semi-implicit step (seed 000 eq. 2.2-14/15)."""

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._numerics import take_rows
from .._types import PRESSURE_KINDS, Kinds, is_kind
from ..operators import Pairs
from ._cg import SolveInfo, solve_spd
from ._precondition import Apply, PressureSystem


def assemble_pressure_system(
    pairs: Pairs,
    kind: Kinds,
    active: Bool[Array, " n"],
    surface: Bool[Array, " n"],
    coefficient: Float[Array, "n k"] | None = None,
) -> PressureSystem:
    """The PPE operator A (symmetric positive definite) in pair form.

    For a particle i in the system S (active fluid/wall/body, not on the surface):
        (A p)_i = sum_j c_ij (p_i - [j in S] p_j),
    with c_ij the Laplacian's pair coefficient (default w_ij, the standard
    Laplacian) for pressure-carrying neighbours j. Surface neighbours have
    p_j = 0 (Dirichlet) and stay in the diagonal; dummy neighbours drop out of both
    the diagonal and the off-diagonal terms (a zero-gradient Neumann wall, seed 000
    §2.4.2; a dummy pressure P_i + q_ij that follows its row's, such as
    `SemiImplicit.dummy_head`'s hydrostatic one, adds sum_j c_ij q_ij to the
    right-hand side and leaves A as it is). Rows outside S are the identity, so
    their pressure solves to 0.

    A particle with no pressure-carrying neighbour is not in S either, though its
    number density (dummies count) can be full: a fluid particle that has crossed
    a wall's first layer into the dummies behind it. Its row would be 0 = b_i and
    the solve would break down (a NaN in a 3-D tsunami run); it takes its
    Dirichlet value, as a surface particle does.
    """
    carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
    c = pairs.weight if coefficient is None else coefficient
    coupling = jnp.where(pairs.valid & take_rows(carries, pairs.index), c, 0.0)
    diag = jnp.sum(coupling, axis=1)
    in_system = carries & ~surface & (diag > 0)
    off = jnp.where(take_rows(in_system, pairs.index), coupling, 0.0)
    return PressureSystem(index=pairs.index, off=off, diag=diag, in_system=in_system)


def pressure_system(
    pairs: Pairs,
    kind: Kinds,
    active: Bool[Array, " n"],
    surface: Bool[Array, " n"],
    coefficient: Float[Array, "n k"] | None = None,
):
    """(matvec, diagonal, row mask) of `assemble_pressure_system`; the diagonal is
    1 on rows outside the system."""
    system = assemble_pressure_system(pairs, kind, active, surface, coefficient)
    return system.matvec, 1.0 / system.inverse_diagonal, system.in_system


def solve_pressure(
    pairs: Pairs,
    kind: Kinds,
    active: Bool[Array, " n"],
    surface: Bool[Array, " n"],
    source: Float[Array, " n"],
    guess: Float[Array, " n"],
    rtol: float,
    atol: float,
    max_iterations: int,
    coefficient: Float[Array, "n k"] | None = None,
    preconditioner: Callable[[PressureSystem], Apply] | None = None,
    boundary: Float[Array, " n"] | None = None,
) -> tuple[Float[Array, " n"], SolveInfo]:
    """Solve A p = source on the system rows (source is ignored elsewhere).

    `preconditioner` builds M^-1 from the (gradient-stopped) system, e.g.
    `functools.partial(Multigrid(), grid, disc, position)`; None is Jacobi.
    `boundary`: the Dirichlet values of the surface particles (None: 0), which
    they keep in the returned pressure; a system row's right-hand side gains
    sum_j c_ij boundary_j over its surface neighbours."""
    system = assemble_pressure_system(pairs, kind, active, surface, coefficient)
    if boundary is not None:
        carries = jnp.logical_and(active, is_kind(kind, PRESSURE_KINDS))
        fixed = jnp.where(carries & ~system.in_system, boundary, 0.0)
        c = pairs.weight if coefficient is None else coefficient
        c = jnp.where(pairs.valid, c, 0.0)
        source = source + jnp.sum(c * take_rows(fixed, pairs.index), axis=1)
    b = jnp.where(system.in_system, source, 0.0)
    x0 = jnp.where(system.in_system, guess, 0.0)
    stopped = jax.lax.stop_gradient(system)
    apply = (
        stopped.inverse_diagonal if preconditioner is None else preconditioner(stopped)
    )
    pressure, info = solve_spd(system.matvec, b, x0, apply, rtol, atol, max_iterations)
    if boundary is not None:
        pressure = jnp.where(system.in_system, pressure, fixed)
    return pressure, info
