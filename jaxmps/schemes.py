"""Named discretisation presets: keyword arguments of `make_scene`.

Each correction of the high-accuracy scheme is a strategy object in its own slot
(weight, Laplacian, gradient, solver source, solver stabiliser), so a preset is
only a choice of objects, and the ablation ladder of seed 001 is a set of toggles:

    scene = jaxmps.make_scene(position, l0, domain, **jaxmps.schemes.high_accuracy())
    scene = jaxmps.make_scene(..., **jaxmps.schemes.high_accuracy(wendland=False))
"""

import dataclasses
from typing import Any

from .fluid import (
    DensitySource,
    DynamicCompensation,
    DynamicStabilisation,
    HigherOrderSource,
    SemiImplicit,
)
from .operators import (
    CorrectedGradient,
    HigherOrderLaplacian,
    MinimumPressureGradient,
    MPSWeight,
    StandardLaplacian,
    WendlandWeight,
)


def standard(solver: SemiImplicit | None = None) -> dict[str, Any]:
    """The default scheme (seed 000): standard weight r_e/r - 1 at r_e = 2.1 l0, the
    lambda Laplacian, the corrected gradient with the minimum-pressure shift, the
    mixed source, negative pressures clamped and the collision guard on."""
    return dict(
        r_e=2.1,
        weight=MPSWeight(),
        laplacian=StandardLaplacian(),
        gradient=CorrectedGradient(minimum_shift=True),
        solver=SemiImplicit() if solver is None else solver,
    )


def standard_mps(solver: SemiImplicit | None = None) -> dict[str, Any]:
    """The standard MPS of seed 001 §2 (Koshizuka's textbook), the baseline the
    high-accuracy scheme is measured against: weight r_e/r - 1 at r_e = 2.4 l0, the
    lambda Laplacian, the source rho0/dt^2 (n0 - n*)/n0 as printed, Koshizuka's
    minimum-pressure gradient, negative pressures clamped.

    Kept to reproduce the seed's comparison, not for production: its pressure
    noise in the 0.2 m hydrostatic tank at l0 = 1 cm, dt = 1 ms is ~125 % of rho g H
    (benchmarks/results/scheme_cost_cpu.md), against ~1 % for `standard`.
    """
    # Choice: the collision guard of `SemiImplicit` stays on (seed 001 §2 names
    # none). Without it this scheme blows up within 1 s of that tank.
    base = SemiImplicit() if solver is None else solver
    return dict(
        r_e=2.4,
        weight=MPSWeight(),
        laplacian=StandardLaplacian(),
        gradient=MinimumPressureGradient(),
        solver=dataclasses.replace(
            base, source=DensitySource(), clamp_negative_pressure=True
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
) -> dict[str, Any]:
    """MPS-HS-HL-ECS-GC-DS-WEND of seed 001 (r_e = 2.4 l0), with each correction a
    toggle (all on: the seed's combination; all off: `standard` at r_e):

    - hs: higher-order source with the Tanaka-Masunaga term (gamma = 1e-3);
    - hl: higher-order Laplacian in the pressure equation and the viscous term;
    - ecs: dynamic error-compensating source (needs hs);
    - gc_ds: corrected gradient without the minimum-pressure shift, negative
      pressure kept, dynamic stabilisation instead of the collision guard;
    - wendland: the Wendland weight in every operator;
    - normalised: HS and HL normalised on the reference lattice (see the choice
      in `HigherOrderLaplacian`); False (default) keeps the printed scales.

    `solver` supplies the remaining solver settings (tolerance, iteration cap,
    free surface); its source, stabiliser, clamping and guard are replaced.
    """
    if ecs and not hs:
        raise ValueError("ecs=True needs hs=True (the ECS term is part of HS).")
    base = SemiImplicit() if solver is None else solver
    changes: dict[str, Any] = {}
    if hs:
        changes["source"] = HigherOrderSource(
            compensation=DynamicCompensation() if ecs else None,
            normalised=normalised,
        )
    if gc_ds:
        changes.update(
            stabiliser=DynamicStabilisation(),
            clamp_negative_pressure=False,
            collision_distance=None,
        )
    return dict(
        r_e=r_e,
        weight=WendlandWeight() if wendland else MPSWeight(),
        laplacian=HigherOrderLaplacian(normalised=normalised)
        if hl
        else StandardLaplacian(),
        gradient=CorrectedGradient(minimum_shift=not gc_ds),
        solver=dataclasses.replace(base, **changes),
    )


# The cumulative ablation ladder of seed 001 §3 (MPS -> ... -> full scheme).
LADDER = {
    "standard": dict(hs=False, hl=False, ecs=False, gc_ds=False, wendland=False),
    "HS": dict(hs=True, hl=False, ecs=False, gc_ds=False, wendland=False),
    "HS-HL": dict(hs=True, hl=True, ecs=False, gc_ds=False, wendland=False),
    "HS-HL-ECS": dict(hs=True, hl=True, ecs=True, gc_ds=False, wendland=False),
    "HS-HL-ECS-GC-DS": dict(hs=True, hl=True, ecs=True, gc_ds=True, wendland=False),
    "high_accuracy": dict(hs=True, hl=True, ecs=True, gc_ds=True, wendland=True),
}
