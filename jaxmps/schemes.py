"""Discretisation schemes: the `Scheme` record and its named presets.

A scheme is the set of models a Scene is discretised with (influence radius,
weight, Laplacian, gradient, pressure stage, free surface, collision guard,
stabiliser). `make_scene` takes one (`scheme=`, default `standard()`); this module
is the one place where a scheme's choice of models is written (each model's own
settings, a tolerance or a guard distance, default in its class). Each correction of the
high-accuracy scheme is a strategy object in its own slot, so a preset is only a
choice of objects, and the ablation ladder of seed 001 is a set of toggles:

    ha = jaxmps.schemes.high_accuracy()
    scene = jaxmps.make_scene(position, l0, domain, scheme=ha)
    scene = jaxmps.make_scene(..., scheme=schemes.high_accuracy(wendland=False))
"""

import dataclasses

import equinox as eqx

from .fluid import (
    AbstractPressureSolver,
    CollisionGuard,
    DensitySource,
    DynamicCompensation,
    DynamicStabilisation,
    Explicit,
    FreeSurface,
    HigherOrderSource,
    SemiImplicit,
)
from .operators import (
    AbstractGradient,
    AbstractLaplacian,
    AbstractWeight,
    CorrectedGradient,
    EMPSGradientWeight,
    EMPSWeight,
    HigherOrderLaplacian,
    MinimumPressureGradient,
    MPSWeight,
    StandardLaplacian,
    SymmetricGradient,
    WendlandWeight,
)


class Scheme(eqx.Module):
    """The models a Scene is discretised with.

    Attributes:
        r_e: influence radius in units of the spacing l0 (2.1 in seed 000, 2.4 in
            seed 001).
        weight: the weight function of every operator.
        laplacian: Laplacian of the viscous term and the pressure equation.
        gradient: the pressure-gradient model.
        solver: the pressure stage (`SemiImplicit` or `Explicit`).
        surface: free-surface detection, or None.
        collision: collision guard on the predicted velocities, or None.
        stabiliser: dynamic stabilisation after the correction, or None.
    """

    r_e: float
    weight: AbstractWeight
    laplacian: AbstractLaplacian
    gradient: AbstractGradient
    solver: AbstractPressureSolver
    surface: FreeSurface | None
    collision: CollisionGuard | None
    stabiliser: DynamicStabilisation | None

    def __check_init__(self):
        if not self.r_e > 1:
            raise ValueError(
                f"Scheme.r_e must be > 1 (in units of l0), got {self.r_e}."
            )
        if self.solver.needs_surface and self.surface is None:
            raise ValueError(
                f"{type(self.solver).__name__} needs a free-surface model "
                "(`surface=FreeSurface()`)."
            )

    def replace(self, **changes) -> "Scheme":
        """This scheme with some models replaced (keyword per attribute)."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise ValueError(
                f"Scheme has no {sorted(unknown)}; its models are "
                f"{[f.name for f in dataclasses.fields(self)]}."
            )
        return dataclasses.replace(self, **changes)


def standard(
    solver: SemiImplicit | None = None, *, dynamic_stabilisation: bool = False
) -> Scheme:
    """The default scheme (seed 000): standard weight r_e/r - 1 at r_e = 2.1 l0, the
    lambda Laplacian, the corrected gradient with the minimum-pressure shift, the
    mixed source, negative pressures clamped, the beta free-surface rule with the
    isolated-surface filter and the collision guard.

    `dynamic_stabilisation=True` (scene setting `scheme=standard_ds`) keeps the
    corrected gradient as seed 000 prints it, without the shift, and stabilises it
    by seed 001's dynamic stabilisation instead of the shift and the collision
    guard. Measured at l0 = 1 cm (validation/sloshing_free_decay.py,
    still_water_noise.py): the first sloshing mode's period -0.7 / +0.3 / +0.0 % of
    linear theory at h/L 0.2 / 0.4 / 0.6 (default: -3.3 / -2.0 / -2.8 %), and at
    the scenes' default step the still-water bottom pressure 1.5-21x quieter
    (0.2-1.0 % of rho g H over seven tanks at 1 and 2 cm, default 0.9-5.7 %; at
    dt_max = 0.5 ms 0.11-0.65 %, default 0.9-6.1 %, with the density relaxed per
    calm step, `relaxation_step="calm"`; relaxed per step noisier than the
    default in two of seven), and the heave of a floating box within
    1 % of linear potential flow's period, its decay 1.1 x (default 1.9 x;
    validation/heave_decay.py), for a semi-implicit step 11-29 %
    dearer (dam break, 7k particles, benchmarks/NOTES.md §16). Measured once at
    h/L 0.2 / 0.4 / 0.6, dynamic stabilisation with the shift kept gave -1.5 /
    -2.2 / -1.5 %: both the guard and the shift shorten the period. The unshifted
    gradient with only the collision guard is unstable at the contact line (see
    `CorrectedGradient`)."""
    scheme = Scheme(
        r_e=2.1,
        weight=MPSWeight(),
        laplacian=StandardLaplacian(),
        gradient=CorrectedGradient(minimum_shift=True),
        solver=SemiImplicit() if solver is None else solver,
        surface=FreeSurface(),
        collision=CollisionGuard(),
        stabiliser=None,
    )
    if dynamic_stabilisation:
        scheme = scheme.replace(
            gradient=CorrectedGradient(),
            collision=None,
            stabiliser=DynamicStabilisation(),
        )
    return scheme


def explicit(solver: Explicit | None = None) -> Scheme:
    """Explicit MPS (E-MPS, seed 002) at r_e = 2.1 l0: the equation of state, the
    E-MPS weight w = r_e/r + r/r_e - 2 of number density and Laplacian, the
    symmetric gradient with its own weight r_e/r - r/r_e; no surface detection (the
    equation of state sets P = 0 where n* <= n0) and no collision guard."""
    return Scheme(
        r_e=2.1,
        weight=EMPSWeight(),
        laplacian=StandardLaplacian(),
        gradient=SymmetricGradient(weight=EMPSGradientWeight()),
        solver=Explicit() if solver is None else solver,
        surface=None,
        collision=None,
        stabiliser=None,
    )


def standard_mps(
    solver: SemiImplicit | None = None, surface_head: float = 0.0
) -> Scheme:
    """The standard MPS of seed 001 §2 (Koshizuka's textbook), the baseline the
    high-accuracy scheme is measured against: weight r_e/r - 1 at r_e = 2.4 l0, the
    lambda Laplacian, the source rho0/dt^2 (n0 - n*)/n0 as printed, Koshizuka's
    minimum-pressure gradient, negative pressures clamped, P = 0 at the surface
    particles (`surface_head`, replacing the solver's) and zero-gradient dummies.

    Kept to reproduce the seed's comparison, not for production: its pressure
    noise in the 0.2 m hydrostatic tank at l0 = 1 cm, dt = 1 ms is ~125 % of rho g H
    (benchmarks/results/scheme_cost_cpu.md), against ~1 % for `standard`.
    """
    # Choice: the collision guard stays on (seed 001 §2 names none). Without it this
    # scheme blows up within 1 s of that tank.
    base = SemiImplicit() if solver is None else solver
    base = dataclasses.replace(base, surface_head=surface_head)
    return standard().replace(
        r_e=2.4,
        gradient=MinimumPressureGradient(),
        solver=dataclasses.replace(
            base,
            source=DensitySource(),
            clamp_negative_pressure=True,
            dummy_head=False,
        ),
    )


def high_accuracy(
    solver: SemiImplicit | None = None,
    *,
    hs: bool = True,
    hl: bool = True,
    ecs: bool = True,
    gc_ds: bool = True,
    wendland: bool = True,
    normalised: bool = False,
    r_e: float = 2.4,
    gamma: float = 0.02,
) -> Scheme:
    """MPS-HS-HL-ECS-GC-DS-WEND of seed 001 (r_e = 2.4 l0), with each correction a
    toggle (all on: the seed's combination; all off: `standard` at r_e):

    - hs: higher-order source with the Tanaka-Masunaga term, relaxation `gamma`
      per step (seed 001 prints 1e-3 at steps 4-8 times shorter than our
      defaults; see `HigherOrderSource.gamma`);
    - hl: higher-order Laplacian in the pressure equation and the viscous term;
    - ecs: dynamic error-compensating source (needs hs);
    - gc_ds: corrected gradient without the minimum-pressure shift, negative
      pressure kept, dynamic stabilisation instead of the collision guard;
    - wendland: the Wendland weight in every operator;
    - normalised: HS and HL normalised on the reference lattice (see the choice
      in `HigherOrderLaplacian`); False (default) keeps the printed scales.

    `solver` supplies the remaining solver settings (tolerance, iteration cap,
    preconditioner, surface head); its source and clamping are replaced.
    """
    if ecs and not hs:
        raise ValueError("ecs=True needs hs=True (the ECS term is part of HS).")
    scheme = standard(solver).replace(r_e=r_e)
    if hs:
        source = HigherOrderSource(
            gamma=gamma,
            compensation=DynamicCompensation() if ecs else None,
            normalised=normalised,
        )
        scheme = scheme.replace(
            solver=dataclasses.replace(scheme.solver, source=source)
        )
    if hl:
        scheme = scheme.replace(laplacian=HigherOrderLaplacian(normalised=normalised))
    if gc_ds:
        scheme = scheme.replace(
            gradient=CorrectedGradient(minimum_shift=False),
            solver=dataclasses.replace(scheme.solver, clamp_negative_pressure=False),
            collision=None,
            stabiliser=DynamicStabilisation(),
        )
    if wendland:
        scheme = scheme.replace(weight=WendlandWeight())
    return scheme


# The cumulative ablation ladder of seed 001 §3 (MPS -> ... -> full scheme).
LADDER = {
    "standard": dict(hs=False, hl=False, ecs=False, gc_ds=False, wendland=False),
    "HS": dict(hs=True, hl=False, ecs=False, gc_ds=False, wendland=False),
    "HS-HL": dict(hs=True, hl=True, ecs=False, gc_ds=False, wendland=False),
    "HS-HL-ECS": dict(hs=True, hl=True, ecs=True, gc_ds=False, wendland=False),
    "HS-HL-ECS-GC-DS": dict(hs=True, hl=True, ecs=True, gc_ds=True, wendland=False),
    "high_accuracy": dict(hs=True, hl=True, ecs=True, gc_ds=True, wendland=True),
}
