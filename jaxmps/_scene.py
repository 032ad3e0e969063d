"""Scene: the static description of a simulation (shapes, discretisation, models)."""

import equinox as eqx

from .bodies import RigidBodies
from .fluid import AbstractSolver, Inflow, Outflow, PrescribedMotion, SemiImplicit
from .neighbours import Grid
from .operators import (
    AbstractGradient,
    AbstractLaplacian,
    AbstractWeight,
    CorrectedGradient,
    MPSWeight,
    StandardLaplacian,
)


class Scene(eqx.Module):
    """Everything that fixes a shape, a loop bound or a branch. Changing it recompiles.

    Build one with `jaxmps.make_scene` rather than by hand: it derives n0, lambda and
    the capacities from the initial particles.

    Attributes:
        dim: spatial dimension (2 or 3); the last axis is vertical.
        capacity: number of particle slots n (active and pooled).
        spacing: initial particle spacing l0 [m].
        r_e: influence radius [m].
        n0: reference particle number density of the lattice.
        lam: Laplacian coefficient lambda [m^2].
        grid: neighbour-search cell grid; its box is the domain.
        max_neighbours: neighbour slots per particle.
        neighbour_skin: the lists are searched within r_e + neighbour_skin [m], so
            that those built at the predicted positions of one step serve the start
            of the next while no particle has moved by half the skin
            (`neighbours.NeighbourCache`); 0 searches twice per step.
        courant_limit: largest max|u| dt / l0 accepted before `Result.step_too_large`.
        viscous_limit: largest viscous number 2 d nu dt / lambda accepted (the
            explicit viscous term's diffusion limit); beyond it a concrete dt is
            refused at the start and a traced one ends the run with
            `Result.step_too_large`. Measured onset of instability in a 2-D tank:
            1.5 (semi-implicit, MPS weight), 1.3 (explicit, E-MPS weight).
        weight: weight function of every operator.
        laplacian: Laplacian model of the viscous term and the pressure equation.
        gradient: pressure-gradient model.
        solver: how the fluid is advanced (`SemiImplicit()` or `Explicit()`).
        inflow: optional moving inflow boundary fed from the inactive pool.
        outflow: optional outflow plane returning fluid to the pool.
        motion: optional prescribed motion of wall particles (piston, shaken tank).
        rigid: optional rigid bodies (with contact and friction).
    """

    dim: int
    capacity: int
    spacing: float
    r_e: float
    n0: float
    lam: float
    grid: Grid
    max_neighbours: int
    neighbour_skin: float = 0.0
    courant_limit: float = 0.5
    viscous_limit: float = 1.0
    weight: AbstractWeight = MPSWeight()
    laplacian: AbstractLaplacian = StandardLaplacian()
    gradient: AbstractGradient = CorrectedGradient(minimum_shift=True)
    solver: AbstractSolver = SemiImplicit()
    inflow: Inflow | None = None
    outflow: Outflow | None = None
    motion: PrescribedMotion | None = None
    rigid: RigidBodies | None = None

    def max_viscous_dt(self, viscosity: float) -> float:
        """The viscous limit dt <= viscous_limit lambda / (2 d nu) [s]; inf at nu=0."""
        if viscosity <= 0:
            return float("inf")
        return self.viscous_limit * self.lam / (2 * self.dim * viscosity)

    def __check_init__(self):
        if self.dim not in (2, 3):
            raise ValueError(f"Scene.dim must be 2 or 3, got {self.dim}.")
        if len(self.grid.shape) != self.dim:
            raise ValueError("Scene.grid must have one axis per dimension.")
        if not self.neighbour_skin >= 0:
            raise ValueError(
                f"Scene.neighbour_skin must be >= 0, got {self.neighbour_skin}."
            )
        if self.grid.radius < (self.r_e + self.neighbour_skin) * (1 - 1e-12):
            raise ValueError(
                "Scene.grid.cell_size x Scene.grid.reach must be >= r_e + "
                "neighbour_skin; build the Scene with `make_scene`."
            )
        if self.max_neighbours < 1 or self.capacity < 1:
            raise ValueError("Scene.max_neighbours and Scene.capacity must be >= 1.")
