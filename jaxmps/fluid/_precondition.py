"""Preconditioners of the pressure system: Jacobi and aggregation multigrid."""

import abc
import itertools
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._numerics import HIGHEST, materialised, pair_differences, take_rows
from ..neighbours import Grid
from ..operators import Discretisation

# The pressure product is summed slot by slot for rows of at most SLOTWISE_SLOTS
# slots (2-D) in systems of at least SLOTWISE_PARTICLES rows. Measured at 25k
# particles (2-D dam break, benchmarks/NOTES.md §15): the semi-implicit step 15-20 %
# faster in float64 and float32; compiling a step takes ~2.5 s longer, which a small
# system never earns back. In 3-D (64-80 slots) the loop was slower (§6).
SLOTWISE_SLOTS = 32
SLOTWISE_PARTICLES = 8192


class PressureSystem(eqx.Module):
    """The PPE matrix in pair form: for i in the system S,
    (A p)_i = diag_i p_i - sum_k off_ik p_index_ik; rows outside S are the identity.
    `off` is zero for neighbours outside S and for empty slots (index n)."""

    index: Int[Array, "n k"]
    off: Float[Array, "n k"]
    diag: Float[Array, " n"]
    in_system: Bool[Array, " n"]

    def matvec(self, p: Float[Array, " n"]) -> Float[Array, " n"]:
        n, k = self.index.shape
        if k <= SLOTWISE_SLOTS and n >= SLOTWISE_PARTICLES:
            # Slot by slot, which XLA fuses into one loop; a gather of the (n, k)
            # block summed over its rows runs as a separate row reduction.
            coupled = self.off[:, 0] * take_rows(p, self.index[:, 0])
            for s in range(1, k):
                coupled = coupled + self.off[:, s] * take_rows(p, self.index[:, s])
        else:
            coupled = jnp.sum(self.off * take_rows(p, self.index), axis=1)
        return jnp.where(self.in_system, self.diag * p - coupled, p)

    @property
    def inverse_diagonal(self) -> Float[Array, " n"]:
        # `assemble_pressure_system` leaves rows with no pressure-carrying
        # neighbour out of S; a system built otherwise is guarded anyway.
        ok = self.in_system & (self.diag > 0)
        return jnp.where(ok, 1.0 / jnp.where(ok, self.diag, 1.0), 1.0)


Apply = Callable[[Float[Array, " n"]], Float[Array, " n"]]


class AbstractPreconditioner(eqx.Module):
    """Builds, once per pressure solve, a symmetric positive definite approximation
    z = M^-1 r of the inverse of the pressure matrix."""

    @abc.abstractmethod
    def __call__(
        self,
        grid: Grid,
        disc: Discretisation,
        position: Float[Array, "n d"],
        system: PressureSystem,
    ) -> Apply:
        """z = M^-1 r for the `system` (built from gradient-stopped values) of the
        particles at `position`, in the neighbour `grid`'s box."""


class Jacobi(AbstractPreconditioner):
    """M = diag(A). Cheapest per iteration; CG then needs O(n^(1/d)) iterations
    (48 at 1k to 508 at 98k particles in the 2-D dam break, float32, rtol 1e-5)."""

    def __call__(
        self,
        grid: Grid,
        disc: Discretisation,
        position: Float[Array, "n d"],
        system: PressureSystem,
    ) -> Apply:
        del grid, disc, position
        inverse = system.inverse_diagonal
        return lambda r: inverse * r


def _halvings(shape: tuple[int, ...], coarsest_cells: int):
    """Per-level halving factors (1 or 2 per axis) and the padded level shapes,
    coarsening every axis longer than 2 until at most `coarsest_cells` remain."""
    sizes, factors = [tuple(shape)], []
    while math.prod(sizes[-1]) > coarsest_cells:
        f = tuple(2 if s > 2 else 1 for s in sizes[-1])
        if f == (1,) * len(f):
            break
        factors.append(f)
        sizes.append(tuple(-(-s // k) for s, k in zip(sizes[-1], f)))
    padded = [sizes[-1]]
    for f in reversed(factors):
        padded.insert(0, tuple(s * k for s, k in zip(padded[0], f)))
    return padded, factors


def _coarsening(radius: tuple[int, ...], factor: tuple[int, ...]):
    """Static map of the Galerkin product R A P on a cell grid: the coarse stencil
    entry of offset t sums the fine entries (offset s, child a) with
    floor((a + s) / factor) = t. Returns (matrix, coarse radius per axis)."""
    fine = _box(radius)
    coarse_radius = tuple(-(-r // k) for r, k in zip(radius, factor))
    coarse = _box(coarse_radius)
    where = {tuple(c): i for i, c in enumerate(coarse)}
    children = list(itertools.product(*[range(k) for k in factor]))
    matrix = np.zeros((len(coarse), len(fine) * len(children)))
    for s, offset in enumerate(fine):
        for a, child in enumerate(children):
            t = tuple((np.asarray(child) + offset) // np.asarray(factor))
            matrix[where[t], s * len(children) + a] = 1.0
    return matrix, coarse_radius


def _box(radius: tuple[int, ...]) -> np.ndarray:
    ranges = [range(-r, r + 1) for r in radius]
    return np.array(list(itertools.product(*ranges)), dtype=np.int32).reshape(
        -1, len(radius)
    )


def _parent(shape: tuple[int, ...], factor: tuple[int, ...]) -> np.ndarray:
    cells = np.indices(shape).reshape(len(shape), -1).T // np.asarray(factor)
    coarse = tuple(s // k for s, k in zip(shape, factor))
    return np.ravel_multi_index(tuple(cells.T), coarse).astype(np.int32)


def _stencil_apply(coeff, x, radius):
    """y_I = sum_s coeff[s, I] x[I + offset_s] on a cell grid (zero outside)."""
    pad = jnp.pad(x, [(r, r) for r in radius])
    y = jnp.zeros_like(x)
    for s, offset in enumerate(_box(radius)):
        window = tuple(
            slice(r + int(o), r + int(o) + n)
            for r, o, n in zip(radius, offset, x.shape)
        )
        y = y + coeff[s] * pad[window]
    return y


def _coarsen(coeff, radius, factor):
    """Galerkin coarse stencil (R A P, piecewise-constant P) of a cell-grid stencil."""
    dim = coeff.ndim - 1
    matrix, coarse_radius = _coarsening(radius, factor)
    shape = coeff.shape[1:]
    split = coeff.reshape(
        (coeff.shape[0],) + sum(((s // k, k) for s, k in zip(shape, factor)), ())
    )
    order = (
        (0,)
        + tuple(2 + 2 * a for a in range(dim))
        + tuple(1 + 2 * a for a in range(dim))
    )
    coarse_shape = tuple(s // k for s, k in zip(shape, factor))
    blocked = split.transpose(order).reshape((-1,) + coarse_shape)
    return jnp.tensordot(
        jnp.asarray(matrix, coeff.dtype), blocked, axes=1, precision=HIGHEST
    ), coarse_radius


def _dense_factor(coeff, radius):
    """Cholesky factor of the coarsest stencil as a dense matrix. Empty cells get an
    identity row; a relative shift of sqrt(eps) keeps the factor finite."""
    shape = coeff.shape[1:]
    n = math.prod(shape)
    cells = np.indices(shape).reshape(len(shape), -1).T
    rows, cols, entries = [], [], []
    for s, offset in enumerate(_box(radius)):
        other = cells + offset
        inside = np.all((other >= 0) & (other < np.asarray(shape)), axis=1)
        rows.append(np.ravel_multi_index(tuple(cells[inside].T), shape))
        cols.append(np.ravel_multi_index(tuple(other[inside].T), shape))
        entries.append(np.full(int(inside.sum()), s))
    rows, cols, entries = (np.concatenate(v) for v in (rows, cols, entries))
    flat = coeff.reshape(coeff.shape[0], n)
    a = jnp.zeros((n, n), coeff.dtype).at[rows, cols].add(flat[entries, rows])
    d = jnp.diagonal(a)
    shift = jnp.finfo(coeff.dtype).eps ** 0.5
    a = a + jnp.diag(jnp.where(d > 0, shift * d, 1.0))
    return jax.scipy.linalg.cho_factor(a, lower=True)


def _safe_inverse(d):
    return jnp.where(d > 0, 1.0 / jnp.where(d > 0, d, 1.0), 0.0)


def _flat_cells(cells: Int[Array, "n d"], shape: tuple[int, ...]) -> Int[Array, " n"]:
    """The flat index of each particle's cell, written out once (`materialised`):
    every pair slot and every V-cycle reads it."""
    return materialised(jnp.ravel_multi_index(tuple(cells.T), shape, mode="clip"))


def _offset_code(
    cells: Int[Array, "n d"],
    flat: Int[Array, " n"],
    index: Int[Array, "n k"],
    shape: tuple[int, ...],
) -> Int[Array, "n k"]:
    """The stencil plane of every listed pair: its neighbour cell's offset from
    the particle's own, each axis clipped to [-1, 1] and read as base-3 digits in
    `_box((1,) * d)` order.

    One gather per pair of the (materialised) flat cell index rather than one
    per axis, the offsets decoded from the difference: flat_j - flat_i =
    sum_a delta_a stride_a is exact while every axis but the first has at least
    3 cells and |delta_a| <= 1, which holds for every pair within r_e of cells of
    edge r_e. Pairs farther apart (a carried list's skin, the sentinel slot)
    decode to some plane in range; their coefficients are 0."""
    if min(shape[1:], default=3) < 3:
        deltas = list(pair_differences(cells, index))
    else:
        rest = take_rows(flat, index) - flat[:, None]
        deltas = []
        for size in reversed(shape[1:]):
            delta = jnp.remainder(rest + 1, size) - 1
            deltas.insert(0, delta)
            rest = (rest - delta) // size
        deltas.insert(0, rest)
    code = jnp.zeros(index.shape, jnp.int32)
    for delta in deltas:
        code = code * 3 + jnp.clip(delta, -1, 1) + 1
    return code


def _cell_stencil(
    system: PressureSystem,
    cells: Int[Array, "n d"],
    shape: tuple[int, ...],
    flat: Int[Array, " n"] | None = None,
) -> Float[Array, "..."]:
    """The Galerkin product P^T A P of the system rows, with P the indicator of
    the particles' `cells` on a grid of `shape` whose edge is at least r_e, as a
    stencil: entry [s, I] couples cell I with cell I + offset s (`_box((1,) * d)`
    order), shape (3^d,) + shape.

    Each pair entry is added to the plane of its neighbour cell's offset at the
    particle's cell, in one scatter of the (n, k) entries (sentinel slots have
    off = 0). Masked row sums per offset and a scatter of the rows cost 3x more on
    the CPU (benchmarks/NOTES.md §22). `flat`: the cells' flat indices
    (`_flat_cells`), if the caller has them."""
    dim = len(shape)
    n1 = math.prod(shape)
    if 3**dim * n1 >= 2**31:
        raise ValueError(
            f"The multigrid's finest cell grid {shape} (cells of edge r_e over the "
            "neighbour grid's box) is too large to index in int32; shrink the "
            "domain or give SemiImplicit(preconditioner=Jacobi())."
        )
    in_system = system.in_system
    flat = _flat_cells(cells, shape) if flat is None else flat
    entry = _offset_code(cells, flat, system.index, shape)
    off = jnp.where(in_system[:, None], system.off, 0.0)
    target = (entry * n1 + flat[:, None]).reshape(-1)
    coeff = jnp.zeros(3**dim * n1, off.dtype).at[target].add(-off.reshape(-1))
    diag = jnp.where(in_system, system.diag, 0.0)
    coeff = coeff.at[(3**dim // 2) * n1 + flat].add(diag)
    return coeff.reshape((3**dim,) + tuple(shape))


class Multigrid(AbstractPreconditioner):
    """Aggregation multigrid V-cycle (one application per CG iteration).

    The particles of the system are aggregated into cubic cells of edge r_e (so a
    particle's neighbours lie in the 3^d cells around its own); the coarse matrix is
    the Galerkin product P^T A P with piecewise-constant P, assembled from the pair
    coefficients (each added to its cell and neighbour-cell offset, `_cell_stencil`).
    Coarser levels halve the cell grid (every axis longer than 2) with the same
    Galerkin product, down to at most `coarsest_cells` cells, which are solved by
    a dense Cholesky factorisation. Every cell level smooths with one
    damped-Jacobi sweep before and one after its coarse correction, so the
    V-cycle is symmetric; it is positive definite while `correction` < 2.

    The particles' own level (`fine`) is either added to the cell hierarchy's
    correction, z = D^-1 r + P C P^T r with C the cells' V-cycle ("additive",
    the default: no product with the particle matrix inside the cycle), or
    smoothed around it like the cell levels ("multiplicative": a Jacobi sweep,
    the residual, the correction, and a second sweep, i.e. two products with
    the particle matrix per application). Measured on pressure systems captured
    from runs (one core, float64 unless said, whole solves to the default
    tolerance): the additive form takes 1.4-1.9x the iterations and each costs
    about half (the particle products are most of a multiplicative cycle), so
    the solves are 15-25 % faster: the 2-D dam break in motion at 6.8k / 25k
    particles 19 -> 29 / 22 -> 32 iterations, 14.9 -> 11.8 / 57.5 -> 44.6 ms;
    25k in float32 19 -> 27, 36.0 -> 28.8 ms; a sloshing tank 14 -> 21, 2.7 ->
    2.0 ms; the 3-D dam break 18 -> 26, 1.20 -> 0.90 s (benchmarks/NOTES.md
    §25).

    All of it is built once per pressure solve, from the matrix of that solve, and
    carries no gradient (the implicit adjoint solve uses it as it is).

    Measured in the 2-D dam break with the multiplicative particle level
    (benchmarks/NOTES.md §3), mean CG iterations per step against Jacobi, float64
    to rtol 1e-9: 247 -> 22.5 at 7k particles, 474 -> 28.5 at 25k; float32 to
    rtol 1e-5: 9 at 1k to 18 at 98k (Jacobi 48 to 508).

    Attributes:
        omega: Jacobi damping of the cell levels' smoother (and of the
            particles' with `fine="multiplicative"`).
        correction: over-correction factor of the (unsmoothed) coarse correction;
            aggregation with piecewise-constant P underestimates the smooth error,
            and 1.5-1.8 halves the iterations against 1.
        coarsest_cells: largest cell count solved directly.
        fine: how the particles' level joins the cells' correction,
            "additive" or "multiplicative" (above).
        single_precision: build and apply the V-cycle in float32 when the system
            is float64 (its result is cast back). The cycle is then symmetric only
            to round-off, which the Polak-Ribiere form of the CG absorbs (one more
            iteration); its cheaper gathers make the float64 step ~8 % faster at 25k
            particles (benchmarks/NOTES.md §4).
    """

    omega: float = 2.0 / 3.0
    correction: float = 1.5
    coarsest_cells: int = 64
    single_precision: bool = True
    fine: str = "additive"

    def __check_init__(self):
        if not 0 < self.omega <= 1:
            raise ValueError(f"Multigrid.omega must lie in (0, 1], got {self.omega}.")
        if not 0 < self.correction < 2:
            raise ValueError(
                f"Multigrid.correction must lie in (0, 2), got {self.correction}."
            )
        if self.coarsest_cells < 1:
            raise ValueError("Multigrid.coarsest_cells must be at least 1.")
        if self.fine not in ("additive", "multiplicative"):
            raise ValueError(
                "Multigrid.fine must be 'additive' or 'multiplicative', got "
                f"{self.fine!r}."
            )

    def layout(self, grid: Grid, disc: Discretisation):
        """Static: (origin, cell edge, padded shapes per level, halving factors)."""
        cell = float(disc.r_e)
        shape = tuple(
            max(1, math.ceil((u - o) / cell - 1e-9))
            for o, u in zip(grid.origin, grid.upper)
        )
        shapes, factors = _halvings(shape, self.coarsest_cells)
        return grid.origin, cell, shapes, factors

    def __call__(
        self,
        grid: Grid,
        disc: Discretisation,
        position: Float[Array, "n d"],
        system: PressureSystem,
    ) -> Apply:
        dtype = system.off.dtype
        if self.single_precision and dtype != jnp.float32:
            low = PressureSystem(
                index=system.index,
                off=system.off.astype(jnp.float32),
                diag=system.diag.astype(jnp.float32),
                in_system=system.in_system,
            )
            apply = self._build(grid, disc, position, low)
            return lambda r: apply(r.astype(jnp.float32)).astype(dtype)
        return self._build(grid, disc, position, system)

    def _build(self, grid, disc, position, system):
        origin, cell, shapes, factors = self.layout(grid, disc)
        dim = len(origin)
        shape = shapes[0]
        lower = jnp.asarray(origin, position.dtype)[None, :]
        cells = jnp.floor((position - lower) / cell).astype(jnp.int32)
        cells = jnp.clip(cells, 0, jnp.asarray(shape, jnp.int32)[None, :] - 1)
        flat = _flat_cells(cells, shape)
        in_system = system.in_system

        coeff = _cell_stencil(system, cells, shape, flat)
        n1 = math.prod(shape)
        levels = [(coeff, (1,) * dim)]
        for f in factors:
            levels.append(_coarsen(*levels[-1], f))
        factor = _dense_factor(*levels[-1])
        inverse = [_safe_inverse(c[c.shape[0] // 2]) for c, _ in levels]
        parents = [jnp.asarray(_parent(s, f)) for s, f in zip(shapes, factors)]
        omega, alpha = self.omega, self.correction

        def cycle(level, r):
            if level == len(levels) - 1:
                solved = jax.scipy.linalg.cho_solve(factor, r.reshape(-1))
                return solved.reshape(r.shape)
            c, radius = levels[level]
            coarse_shape = shapes[level + 1]
            x = omega * inverse[level] * r
            residual = (r - _stencil_apply(c, x, radius)).reshape(-1)
            coarse_r = jnp.zeros(math.prod(coarse_shape), r.dtype)
            coarse_r = coarse_r.at[parents[level]].add(residual)
            e = materialised(cycle(level + 1, coarse_r.reshape(coarse_shape)))
            x = x + alpha * jnp.take(e.reshape(-1), parents[level]).reshape(r.shape)
            return x + omega * inverse[level] * (r - _stencil_apply(c, x, radius))

        inverse_0 = jnp.where(in_system, system.inverse_diagonal, 0.0)

        def add(r):
            r_s = jnp.where(in_system, r, 0.0)
            coarse_r = jnp.zeros(n1, r.dtype).at[flat].add(r_s)
            e = materialised(cycle(0, coarse_r.reshape(shape)).reshape(-1))
            x = inverse_0 * r_s + jnp.where(in_system, jnp.take(e, flat), 0.0)
            return jnp.where(in_system, x, r)

        if self.fine == "additive":
            return add

        def apply(r):
            r_s = jnp.where(in_system, r, 0.0)
            x = omega * inverse_0 * r_s
            residual = jnp.where(in_system, r_s - system.matvec(x), 0.0)
            coarse_r = jnp.zeros(n1, r.dtype).at[flat].add(residual)
            e = materialised(cycle(0, coarse_r.reshape(shape)).reshape(-1))
            x = x + alpha * jnp.where(in_system, jnp.take(e, flat), 0.0)
            x = x + omega * inverse_0 * (r_s - system.matvec(x))
            # Rows outside the system are the identity.
            return jnp.where(in_system, x, r)

        return apply
