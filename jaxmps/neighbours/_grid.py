"""The uniform cell grid of the neighbour search."""

import itertools

import equinox as eqx
import numpy as np


class Grid(eqx.Module):
    """A box of cells of edge `cell_size`, searched `reach` cells in every
    direction, so that `cell_size * reach` >= the search radius (static).

    Attributes:
        origin: lower corner of the domain box [m].
        cell_size: cell edge [m].
        shape: number of cells per axis.
        candidate_capacity: most particles the stencil cells of one particle (the
            (2 reach + 1)^d cells around it) may hold; more sets
            `Result.cell_overflow`.
        reach: stencil half-width in cells (1: cells of the radius and a 3^d
            stencil; 2: half-radius cells and a 5^d stencil, which covers less
            area beyond the radius and so tests fewer candidates).
    """

    origin: tuple[float, ...]
    cell_size: float
    shape: tuple[int, ...]
    candidate_capacity: int
    reach: int = 1

    def __check_init__(self):
        if len(self.origin) != len(self.shape):
            raise ValueError("Grid.origin and Grid.shape must have the same length.")
        if (
            self.cell_size <= 0
            or min(self.shape) < 1
            or self.candidate_capacity < 1
            or self.reach < 1
        ):
            raise ValueError(f"Invalid grid: {self}.")

    @property
    def upper(self) -> tuple[float, ...]:
        return tuple(o + s * self.cell_size for o, s in zip(self.origin, self.shape))

    @property
    def n_cells(self) -> int:
        out = 1
        for s in self.shape:
            out *= s
        return out

    @property
    def radius(self) -> float:
        """The largest search radius this grid serves [m]."""
        return self.cell_size * self.reach


def stencil(dim: int, reach: int) -> np.ndarray:
    """All cell offsets in (-reach..reach)^dim, shape ((2 reach + 1)^dim, dim)."""
    offsets = range(-reach, reach + 1)
    return np.array(list(itertools.product(offsets, repeat=dim)), dtype=np.int32)


def candidate_counts(grid: Grid, position) -> np.ndarray:
    """Host-side (NumPy): for each point, the number of points in its stencil cells,
    i.e. the candidates `neighbours.build` tests for it (used to size
    `Grid.candidate_capacity`)."""
    position = np.asarray(position, dtype=np.float64)
    if position.shape[0] == 0:
        return np.zeros(0, dtype=int)
    dim = position.shape[1]
    upper = np.asarray(grid.shape) - 1
    coords = np.floor((position - np.asarray(grid.origin)) / grid.cell_size)
    coords = np.clip(coords.astype(int), 0, upper)
    s = grid.reach
    # Occupied cells only (a dense count array of a large, sparse domain would
    # not fit in memory).
    extent = tuple(n + 2 * s for n in grid.shape)
    keys = np.ravel_multi_index(tuple((coords + s).T), extent)
    occupied, counts = np.unique(keys, return_counts=True)
    total = np.zeros(len(position), dtype=int)
    for offset in stencil(dim, s):
        other = np.ravel_multi_index(tuple((coords + s + offset).T), extent)
        slot = np.minimum(np.searchsorted(occupied, other), len(occupied) - 1)
        total += np.where(occupied[slot] == other, counts[slot], 0)
    return total
