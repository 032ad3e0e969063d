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
    """Plain PCG loop; never differentiated (it runs inside custom_linear_solve)."""
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

    Differentiated implicitly through `jax.lax.custom_linear_solve`: the backward pass
    is one more CG solve with A (symmetric), never a backpropagation through the
    iterations. Both the forward and the transposed solve normalise their right-hand
    side by its largest entry before iterating and rescale afterwards, so that small
    cotangents cannot underflow the float32 dot products (jax-ml/jax#40254); `rtol`
    is therefore relative to ||b|| and `atol` applies to the normalised system.

    `x0` (warm start) and `precondition` (z = M^-1 r for a symmetric positive
    definite M, or an array of inverse diagonal entries for Jacobi) only steer the
    iteration and carry no gradient: build M from gradient-stopped values.
    """
    x0 = jax.lax.stop_gradient(x0)
    if not callable(precondition):
        inverse = jax.lax.stop_gradient(precondition)
        precondition = lambda r: inverse * r  # noqa: E731

    def normalised(guess):
        def solve(mv, rhs):
            scale = jnp.max(jnp.abs(rhs))
            safe = jnp.where(scale > 0, scale, 1.0)
            start = guess / safe if guess is not None else jnp.zeros_like(rhs)
            x, info = _pcg(
                mv, rhs / safe, start, precondition, rtol, atol, max_iterations
            )
            return x * safe, info

        return solve

    # Choice: own 30-line PCG inside custom_linear_solve rather than lineax.CG, for the
    # right-hand-side normalisation of both solves (lineax cannot scale the transposed
    # solve) and a warm start used only by the forward solve.
    return jax.lax.custom_linear_solve(
        matvec,
        b,
        solve=normalised(x0),
        transpose_solve=normalised(None),
        symmetric=True,
        has_aux=True,
    )
