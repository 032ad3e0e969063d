"""The uniform cell grid of the neighbour search."""

import equinox as eqx


class Grid(eqx.Module):
    """A box of cells of edge `cell_size` >= the search radius (static).

    Attributes:
        origin: lower corner of the domain box [m].
        cell_size: cell edge [m].
        shape: number of cells per axis.
        cell_capacity: most particles one cell may hold; more sets
            `Result.cell_overflow`.
    """

    origin: tuple[float, ...]
    cell_size: float
    shape: tuple[int, ...]
    cell_capacity: int

    def __check_init__(self):
        if len(self.origin) != len(self.shape):
            raise ValueError("Grid.origin and Grid.shape must have the same length.")
        if self.cell_size <= 0 or min(self.shape) < 1 or self.cell_capacity < 1:
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
