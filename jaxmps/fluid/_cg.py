"""Preconditioned conjugate gradients with implicit differentiation."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._numerics import vdot


class SolveInfo(eqx.Module):
    """Diagnostics of one linear solve (forward pass only)."""

    iterations: Int[Array, ""]
    residual: Float[Array, ""]  # final ||r|| / ||b||
    converged: Bool[Array, ""]


def _pcg(matvec, b, x0, precondition, rtol, atol, max_iterations):
    """Plain PCG loop; never differentiated (`_solve` defines its derivative)."""
    b_norm = jnp.linalg.norm(b)
    tol = jnp.maximum(rtol * b_norm, atol)
    r0 = b - matvec(x0)
    z0 = precondition(r0)
    # The search direction p = z + beta p_old is formed at the start of the next
    # iteration, from the carried z: then the preconditioner's output has one
    # consumer in an iteration (the carry; the dots read it), and XLA's CPU backend
    # does not recompute the V-cycle's last fine product inside the direction's
    # update (which split its gathers into 24 kernels: benchmarks/NOTES.md §22).
    beta0, it0 = jnp.zeros((), b.dtype), jnp.asarray(0, jnp.int32)
    init = (x0, r0, z0, jnp.zeros_like(x0), beta0, vdot(r0, z0), it0)

    def cond(carry):
        _, r, _, _, _, _, it = carry
        return (jnp.linalg.norm(r) > tol) & (it < max_iterations)

    def body(carry):
        x, r, z, p, beta, rz, it = carry
        p = z + beta * p
        ap = matvec(p)
        p_ap = vdot(p, ap)
        alpha = jnp.where(p_ap > 0, rz / jnp.where(p_ap > 0, p_ap, 1.0), 0.0)
        x = x + alpha * p
        r = r - alpha * ap
        z_new = precondition(r)
        rz_new = vdot(r, z_new)
        # Polak-Ribiere: equal to Fletcher-Reeves' rz_new / rz for an exactly
        # symmetric M, and robust when M is slightly not (a single-precision
        # preconditioner in a float64 solve: flexible CG, Notay 2000).
        beta = vdot(r, z_new - z) / jnp.where(rz > 0, rz, 1.0)
        beta = jnp.where(rz > 0, jnp.maximum(beta, 0.0), 0.0)
        return x, r, z_new, p, beta, rz_new, it + 1

    x, r, _, _, _, _, it = jax.lax.while_loop(cond, body, init)
    r_norm = jnp.linalg.norm(r)
    residual = r_norm / jnp.where(b_norm > 0, b_norm, 1.0)
    return x, SolveInfo(iterations=it, residual=residual, converged=r_norm <= tol)


def solve_spd(
    matvec: Callable[[Float[Array, " n"]], Float[Array, " n"]],
    b: Float[Array, " n"],
    x0: Float[Array, " n"],
    precondition: Callable[[Float[Array, " n"]], Float[Array, " n"]]
    | Float[Array, " n"],
    rtol: float,
    atol: float,
    max_iterations: int,
) -> tuple[Float[Array, " n"], SolveInfo]:
    """Solve A x = b for a symmetric positive definite matrix-free A.

    Differentiated implicitly, in both modes: the tangent is the solve of
    A dx = db - dA x (`jax.lax.custom_linear_solve`, which JAX transposes for
    reverse mode into one more CG solve with A, symmetric), never a
    differentiation through the iterations. Every solve normalises its
    right-hand side by its largest entry before iterating and rescales
    afterwards, so that small tangents and cotangents cannot underflow the
    float32 dot products (jax-ml/jax#40254); `rtol` is therefore relative to
    ||b|| and `atol` applies to the normalised system.

    `x0` (warm start) and `precondition` (z = M^-1 r for a symmetric positive
    definite M, or an array of inverse diagonal entries for Jacobi) only steer the
    iteration and carry no derivative.
    """
    x0 = jax.lax.stop_gradient(x0)
    if not callable(precondition):
        inverse = jax.lax.stop_gradient(precondition)
        precondition = lambda r: inverse * r  # noqa: E731
    # The closures become pytrees whose captured arrays are leaves, so that the
    # custom derivative sees what A depends on.
    operator = eqx.filter_closure_convert(matvec, b)
    precondition = eqx.filter_closure_convert(precondition, b)
    return _solve(operator, b, x0, precondition, rtol, atol, max_iterations)


def _normalised_pcg(matvec, b, x0, precondition, rtol, atol, max_iterations):
    """`_pcg` on b scaled by its largest entry (x0 alike), rescaled after."""
    scale = jnp.max(jnp.abs(b))
    safe = jnp.where(scale > 0, scale, 1.0)
    x, info = _pcg(
        matvec, b / safe, x0 / safe, precondition, rtol, atol, max_iterations
    )
    return x * safe, info


# Choice: a custom JVP around the solve, with `custom_linear_solve` only for the
# tangent, rather than `custom_linear_solve(..., has_aux=True)` around it: JAX
# batches a linear solve's aux outputs under `vmap` even when nothing it reads is
# batched, so `jax.jacfwd` (a vmap of JVPs) saw the primal iteration count as
# batched and refused the rollout. Own 30-line PCG rather than lineax.CG, for the
# right-hand-side normalisation of every solve (lineax cannot scale the
# transposed solve) and a warm start used only by the primal solve.
@eqx.filter_custom_jvp
def _solve(operator, b, x0, precondition, rtol, atol, max_iterations):
    return _normalised_pcg(operator, b, x0, precondition, rtol, atol, max_iterations)


@_solve.def_jvp
def _solve_jvp(primals, tangents):
    operator, b, x0, precondition, rtol, atol, max_iterations = primals
    t_operator, t_b = tangents[:2]
    x, info = _solve(*primals)
    rhs = jnp.zeros_like(b) if t_b is None else t_b
    if any(t is not None for t in jax.tree.leaves(t_operator, is_leaf=_is_none)):
        _, a_dot_x = eqx.filter_jvp(lambda op: op(x), (operator,), (t_operator,))
        rhs = rhs - a_dot_x

    def tangent_solve(matvec, rhs):
        zero = jnp.zeros_like(rhs)
        args = (precondition, rtol, atol, max_iterations)
        return _normalised_pcg(matvec, rhs, zero, *args)[0]

    x_dot = jax.lax.custom_linear_solve(
        operator,
        rhs,
        solve=tangent_solve,
        transpose_solve=tangent_solve,
        symmetric=True,
    )
    return (x, info), (x_dot, jax.tree.map(lambda _: None, info))


def _is_none(t) -> bool:
    return t is None
