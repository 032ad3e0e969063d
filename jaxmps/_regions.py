"""Host-side construction of porous damping regions (validates its inputs)."""

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._params import Params, PorousParams
from ._scene import Scene
from ._state import State
from ._types import Kind
from .fluid import (
    PorousRegions,
    direction_axis,
    lowest_porosity,
    pore_weights,
    porosity_field,
    retire,
)


@dataclasses.dataclass(frozen=True)
class PorousRegion:
    """One porous damping region, as given to `add_porous_regions`.

    Attributes:
        box: (lower, upper) corners [m], d numbers each, in the frame of the walls
            at the start of the run; the part inside the domain acts.
        kappa: permeability coefficient [s]: the resistance -u/kappa on the damped
            component (the `porous_kappa` setting of the built-in scenes).
        direction: the damped component: "x", "y", "z", "vertical" (the last
            axis: through horizontal plates) or "all" (`porous_direction`).
        drag: quadratic drag coefficient [1/m], the resistance -drag |u| u
            (`porous_drag`; 0: none).
        porosity: the share of the box open to water, in (0, 1] (`porous_porosity`;
            1: a resistance only, as seed 001's regions). Below 1 the region holds
            that share of the water (rock, a rubble mound): its fluid stands
            sparser and moves with the pore velocity (see `jaxmps.fluid` porous
            module), and a case's fluid in it must be thinned to it
            (`fill_pores`; the built-in scenes do).
    """

    # Any: numbers of any kind (checked by `add_porous_regions`, which names the
    # setting a bad one came from).
    box: Any
    kappa: Any
    direction: str = "vertical"
    drag: Any = 0.0
    porosity: Any = 1.0

    @classmethod
    def of(cls, value) -> "PorousRegion":
        """A region from a `PorousRegion` or a dict of its fields (as a run file's
        config stores it)."""
        if isinstance(value, PorousRegion):
            return value
        if isinstance(value, dict):
            unknown = sorted(set(value) - {f.name for f in dataclasses.fields(cls)})
            if unknown:
                raise ValueError(
                    f"porous_regions: unknown field(s) {unknown}; a region has box, "
                    "kappa, direction, drag, porosity."
                )
            return cls(**value)
        raise ValueError(
            f"porous_regions: expected PorousRegion or dict entries, got "
            f"{type(value).__name__}."
        )

    def as_dict(self) -> dict:
        lower, upper = self.box
        return dict(
            box=[[float(v) for v in lower], [float(v) for v in upper]],
            kappa=float(self.kappa),
            direction=self.direction,
            drag=float(self.drag),
            porosity=float(self.porosity),
        )


def add_porous_regions(
    scene: Scene, params: Params, state: State, regions: Sequence[PorousRegion]
) -> tuple[Scene, Params]:
    """Add porous damping regions (seed 001 eq. 5.1) to a built case: inside each
    box the fluid velocity along the region's direction meets the resistance
    -u/kappa - drag |u| u, added to the predictor and integrated backward over the
    step (`jaxmps.fluid.PorousRegions`). Each region's kappa and drag become
    `Params.porous` entries (differentiable: calibrate "porous.kappa" on a log
    scale).

    In a scene whose prescribed motion moves every wall (a shaken tank) the regions
    move with the walls and damp the velocity relative to them; otherwise they
    are fixed in space.

    A region with a porosity below 1 holds that share of the water: its fluid
    particles weigh 1/porosity in the fluid's sums, which the pressure then holds
    at a sparser packing. The case's fluid in it must be thinned to it once
    (`fill_pores(scene, state)`), or the pressure expels the surplus at the start.

    Refused (ValueError naming the setting): an empty list, a box that is not d
    finite lower and upper numbers with lower < upper, a box entirely outside the
    domain or with no fluid particle in it at the start, kappa not positive and
    finite, drag negative or not finite, a porosity outside (0, 1], an unknown
    direction.

    Returns:
        The Scene with `porous` and the Params with `porous` (the State is
        unchanged).
    """
    regions = [PorousRegion.of(r) for r in regions]
    if not regions:
        raise ValueError("add_porous_regions needs at least one region.")
    if scene.porous is not None:
        raise ValueError(
            "The Scene has porous regions already; give all regions in one "
            "`add_porous_regions` call."
        )
    dim = scene.dim
    origin = np.asarray(scene.grid.origin, float)
    far = origin + np.asarray(scene.grid.shape) * scene.grid.cell_size
    position = np.asarray(state.position)
    fluid = np.asarray(state.active) & (np.asarray(state.kind) == int(Kind.FLUID))
    lowers, uppers, axes = [], [], []
    for region in regions:
        lower, upper = _box(region.box, dim)
        if np.any(upper <= origin) or np.any(lower >= far):
            raise ValueError(
                f"porous_box {_shown(lower, upper)} lies entirely outside the domain "
                f"{_shown(origin, far)}; move it over the fluid."
            )
        inside = fluid & np.all((position >= lower) & (position < upper), axis=1)
        if not np.any(inside):
            raise ValueError(
                f"porous_box {_shown(lower, upper)} holds no fluid particle at the "
                "start; a region acts on fluid only: move or enlarge the box."
            )
        _check_coefficients(region)
        lowers.append(tuple(float(v) for v in lower))
        uppers.append(tuple(float(v) for v in upper))
        axes.append(direction_axis(region.direction, dim))
    porosity = tuple(float(r.porosity) for r in regions)
    porous = any(phi < 1 for phi in porosity)
    if porous and scene.solver.pressure_is_force:
        raise ValueError(
            "porous_porosity below 1 needs the semi-implicit solver "
            "(solver=semi_implicit): the explicit solver's pressure gradient "
            "weighs pairs by its own weight, not the number density's, and held "
            "the sparser water of a region at twice its hydrostatic pressure."
        )
    lowest = lowest_porosity(scene.discretisation)
    if min(porosity) < lowest:
        raise ValueError(
            f"porous_porosity={min(porosity):g} is below {lowest:.3f}, the lowest "
            "this discretisation holds quietly (the water of a region stands "
            "sparser, and below it its particles keep too few neighbours within "
            f"r_e = {scene.discretisation.r_e / scene.discretisation.spacing:g} "
            "l0); raise porous_porosity."
        )
    component = PorousRegions(
        lower=tuple(lowers),
        upper=tuple(uppers),
        axes=tuple(axes),
        moving=_moves_every_wall(scene, state),
        porosity=porosity if porous else None,
        # Choice: two spacings, so that a particle crossing a face at the
        # Courant number 0.1-0.2 changes its weight over 10-20 steps.
        transition=TRANSITION * scene.discretisation.spacing,
        weight_table=pore_weights(scene.discretisation) if porous else None,
    )
    dtype = params.dt.dtype
    coefficients = PorousParams(
        kappa=np.asarray([r.kappa for r in regions], dtype),
        drag=np.asarray([r.drag for r in regions], dtype),
    )
    scene = eqx.tree_at(lambda s: s.porous, scene, component, is_leaf=_none)
    params = eqx.tree_at(lambda p: p.porous, params, coefficients, is_leaf=_none)
    return scene, params


# The width of a porous region's edge, where the porosity passes from 1 to its
# own, in spacings.
TRANSITION = 2.0
# Additive recurrences whose fractional parts fill [0, 1) evenly in any window of
# lattice sites (Roberts' R_d sequences): a site is kept where its value lies
# below the porosity.
_DITHER = {
    2: (0.7548776662466927, 0.5698402909980532),
    3: (0.8191725133961645, 0.6710436067037893, 0.5497004779019703),
}


def fill_pores(scene: Scene, state: State) -> State:
    """`state` with the fluid in porous regions of porosity phi < 1 thinned to phi
    of its particles (the rest returned to the inactive pool, parked at the
    domain's origin): a region then starts holding the water its pores hold.

    The particles kept are spread evenly over the lattice (a site stays where the
    fractional part of its lattice indices times an R_d recurrence lies below
    phi(x), the porosity at it, edges included), deterministic and the same for
    every run of a case. Unchanged without such regions. Call it once: a second
    call thins the kept particles again.
    """
    porous = scene.porous
    if porous is None or not porous.porous:
        return state
    position = np.asarray(state.position, float)
    dim = position.shape[1]
    spacing = scene.discretisation.spacing
    origin = np.asarray(scene.grid.origin, float)
    phi = np.asarray(
        porosity_field(porous, jnp.zeros(dim), jnp.asarray(position)), float
    )
    # Twice the lattice index: whole numbers whether the lattice lies on multiples
    # of l0 or halfway between them (rounding a half would pair sites up).
    sites = np.rint(2.0 * (position - origin) / spacing)
    level = np.mod(sites @ np.asarray(_DITHER[dim]), 1.0)
    water = np.asarray(state.active) & (np.asarray(state.kind) == int(Kind.FLUID))
    gone = water & (phi < 1) & (level >= phi)
    return retire(jnp.asarray(gone), scene.grid, state)


def _none(x) -> bool:
    return x is None


def _box(box, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """The (lower, upper) corners of a `porous_box`, checked."""
    try:
        lower, upper = (np.asarray(corner, float).reshape(-1) for corner in box)
    except (TypeError, ValueError):
        raise ValueError(
            f"porous_box must be (lower, upper) corners of {dim} numbers each "
            f"(on the command line {2 * dim} comma-separated numbers), got {box!r}."
        ) from None
    if lower.shape != (dim,) or upper.shape != (dim,):
        raise ValueError(
            f"porous_box needs {dim} numbers per corner in a {dim}-D scene "
            f"(x0,y0{',z0' if dim == 3 else ''},x1,y1{',z1' if dim == 3 else ''}), "
            f"got {box!r}."
        )
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
        raise ValueError(f"porous_box must be finite, got {box!r}.")
    if np.any(lower >= upper):
        raise ValueError(
            f"porous_box {_shown(lower, upper)}: each lower corner value must lie "
            "below the upper one."
        )
    return lower, upper


def _check_coefficients(region: PorousRegion) -> None:
    kappa, drag = region.kappa, region.drag
    if not (_number(kappa) and math.isfinite(kappa) and kappa > 0):
        raise ValueError(
            f"porous_kappa must be positive and finite (seconds), got {kappa!r}."
        )
    if not (_number(drag) and math.isfinite(drag) and drag >= 0):
        raise ValueError(f"porous_drag must be finite and >= 0 (1/m), got {drag!r}.")
    porosity = region.porosity
    if not (_number(porosity) and 0 < float(porosity) <= 1):
        raise ValueError(
            f"porous_porosity must lie in (0, 1] (the share of the region open to "
            f"water), got {porosity!r}."
        )


def _number(value) -> bool:
    try:
        float(value)
    except (TypeError, ValueError):
        return False
    return not isinstance(value, (bool, np.bool_, str))


def _shown(lower, upper) -> str:
    def corner(values) -> str:
        return "[" + ", ".join(f"{v:g}" for v in values) + "]"

    return f"{corner(lower)} - {corner(upper)}"


def _moves_every_wall(scene: Scene, state: State) -> bool:
    """Whether the Scene's prescribed motion moves every wall and dummy particle
    (a shaken tank), so that regions fixed to the walls move with it."""
    if scene.motion is None:
        return False
    kind = np.asarray(state.kind)
    walls = np.nonzero((kind == int(Kind.WALL)) | (kind == int(Kind.DUMMY)))[0]
    return bool(np.all(np.isin(walls, np.asarray(scene.motion.particles))))
