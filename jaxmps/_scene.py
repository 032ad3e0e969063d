"""Scene: the static description of a simulation (shapes, discretisation, models)."""

from typing import ClassVar

import equinox as eqx

from ._stepping import Adaptive
from .bodies import AbstractBodyModel, ElasticBodies, Grains, RigidBodies
from .fluid import (
    AbstractPressureSolver,
    CollisionGuard,
    DynamicStabilisation,
    FreeSurface,
    Inflow,
    Outflow,
    PorousRegions,
    PrescribedMotion,
)
from .neighbours import Grid
from .operators import (
    AbstractGradient,
    AbstractLaplacian,
    AbstractWeight,
    Discretisation,
)


class Scene(eqx.Module):
    """Everything that fixes a shape, a loop bound or a branch. Changing it recompiles.

    Build one with `jaxmps.make_scene` rather than by hand: it derives n0, lambda and
    the capacities from the initial particles, and takes the discretisation's models
    from a `jaxmps.schemes` preset.

    Attributes:
        discretisation: dim, spacing l0, r_e, n0, lambda and the weight (also
            readable as `scene.dim`, `scene.spacing`, ...).
        capacity: number of particle slots n (active and pooled).
        grid: neighbour-search cell grid; its box is the domain.
        max_neighbours: neighbour slots per particle.
        neighbour_skin: the lists are searched within r_e + neighbour_skin [m], so
            that a rollout carries them from search to search, at the steps'
            starts and predicted positions alike, while no pair of particles has
            moved apart or together by the skin (`neighbours.lists_hold`); 0
            searches twice per step.
        courant_limit: largest max|u| dt / l0 accepted before `Result.step_too_large`.
        viscous_limit: largest viscous number 2 d nu dt / lambda accepted (the
            explicit viscous term's diffusion limit); beyond it a concrete dt is
            refused at the start and a traced one ends the run with
            `Result.step_too_large`. Measured onset of instability in a 2-D tank:
            1.5 (semi-implicit, MPS weight), 1.3 (explicit, E-MPS weight).
        laplacian: Laplacian model of the viscous term and the pressure equation.
        gradient: pressure-gradient model.
        solver: the pressure stage (`SemiImplicit()` or `Explicit()`).
        surface: free-surface detection, or None (the explicit solver's equation
            of state needs none).
        collision: the collision guard on the predicted velocities, or None.
        stabiliser: dynamic stabilisation after the pressure correction, or None.
        inflow: optional moving inflow boundary fed from the inactive pool.
        outflow: optional outflow plane returning fluid to the pool.
        motion: optional prescribed motion of wall particles (piston, shaken tank).
        rigid: optional rigid bodies (with contact and friction).
        elastic: optional elastic bodies.
        grains: optional DEM grains (`jaxmps.add_grains`).
        porous: optional porous damping regions (a resistance on the fluid
            velocity in boxes, `jaxmps.add_porous_regions`).
        escape_limit: how many fluid particles may leave the domain box (spray
            over an open tank) and be taken out of the run, counted in
            `State.escaped`, before the run ends with `Result.left_domain`; 0
            (`make_scene`'s default) ends it at the first.
        time_step: how each step's dt is chosen: None takes `Params.dt` every
            step; `Adaptive()` takes the flow's own limits, at most `Params.dt`.
        body_fields: the fields that hold body models (`AbstractBodyModel`), in the
            order they advance.
    """

    # Choice: the registry of body models. Each model keeps a named, typed field in
    # Scene, Params and State (rather than one tuple of models) so that the records
    # stay typed pytrees the runtime type checks read, and users keep stable paths
    # (`params.rigid.mu_kinetic`, `calibrate(..., "rigid.mu_kinetic")`). Every place
    # that goes over the models (step, checks, frames, run files) reads this tuple:
    # a new model is its module under `bodies/`, its three fields and one entry here.
    body_fields: ClassVar[tuple[str, ...]] = ("rigid", "elastic", "grains")

    discretisation: Discretisation
    capacity: int
    grid: Grid
    max_neighbours: int
    neighbour_skin: float
    courant_limit: float
    viscous_limit: float
    laplacian: AbstractLaplacian
    gradient: AbstractGradient
    solver: AbstractPressureSolver
    surface: FreeSurface | None
    collision: CollisionGuard | None
    stabiliser: DynamicStabilisation | None
    inflow: Inflow | None = None
    outflow: Outflow | None = None
    motion: PrescribedMotion | None = None
    rigid: RigidBodies | None = None
    elastic: ElasticBodies | None = None
    grains: Grains | None = None
    porous: PorousRegions | None = None
    time_step: Adaptive | None = None
    escape_limit: int = 0

    @property
    def body_models(self) -> tuple[AbstractBodyModel, ...]:
        """The body models this Scene has, in the order they advance."""
        models = (getattr(self, name) for name in self.body_fields)
        return tuple(model for model in models if model is not None)

    @property
    def dim(self) -> int:
        return self.discretisation.dim

    @property
    def spacing(self) -> float:
        return self.discretisation.spacing

    @property
    def r_e(self) -> float:
        return self.discretisation.r_e

    @property
    def n0(self) -> float:
        return self.discretisation.n0

    @property
    def lam(self) -> float:
        return self.discretisation.lam

    @property
    def weight(self) -> AbstractWeight:
        return self.discretisation.weight

    def max_viscous_dt(self, viscosity: float) -> float:
        """The viscous limit dt <= viscous_limit lambda / (2 d nu) [s]; inf at nu=0."""
        if viscosity <= 0:
            return float("inf")
        return self.viscous_limit * self.lam / (2 * self.dim * viscosity)

    def __check_init__(self):
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
        if self.solver.needs_surface and self.surface is None:
            raise ValueError(
                f"{type(self.solver).__name__} needs a free-surface model: give the "
                "Scene a `surface=FreeSurface()` (the schemes' presets do)."
            )
