"""The flume's movable bed: DEM grains packed in a pit of the fixed bed below the
groundsill (seed 002 Ch. 6-7), attached to the bed until the flow moves them,
and the probes of the scour hole they leave."""

import math

import numpy as np

from .. import geometry
from .._build_grains import add_grains
from ._probes import BedLowering

# The grains' settings the flume takes (defaults: seed 002 Ch. 6, its quartz
# sand with friction tan 30 degrees; a restitution of 0.1, near the seed's
# critically damped contacts).
MOVABLE_BED = {
    # A movable bed from movable_start (None: the apron's end) over
    # movable_length (0: none), down to movable_depth below the highest bed
    # surface over that stretch.
    "movable_length": 0.0,
    "movable_start": None,
    "movable_depth": 0.05,
    "grain_density": 2650.0,
    "friction": 0.577,
    "restitution": 0.1,
    "lift": 0.2,
    "rolling": 0.0,
    "stiffness": None,  # None: see `_stiffness`
    "contact_capacity": None,
    "substeps": None,
    "on_fluid": False,
}


def movable_stretch(c: dict, profile, length: float):
    """The movable bed's (x0, x1, floor) [m] (None without one): the stretch from
    `movable_start` (the apron's end by default) over `movable_length`, and the
    floor of its pit `movable_depth` below the highest bed over it (ValueError
    naming the settings where it does not fit on the bed). Where the blocks'
    recess lies over it, the floor goes down by up to six spacings more, to
    where a row of the packed bed ends flush with the recess's floor within
    0.134 l0 (`block_sink` lowers the blocks by the rest): the blocks rest on the
    grains, with no gap under them for the bed to settle into."""
    if not c["movable_length"]:
        return None
    l0 = c["spacing"]
    x0 = profile.apron_end if c["movable_start"] is None else c["movable_start"]
    x1 = x0 + c["movable_length"]
    crest = 0.0 if c["crest_length"] is None else c["crest_length"]
    if x0 < crest - 1e-9 or x1 > length - l0 + 1e-9:
        raise ValueError(
            f"the movable bed [{x0:g}, {x1:g}] m (movable_start, movable_length) must "
            f"lie below the crest (x >= crest_length={crest:g} m) and end at least "
            f"one spacing before the bed's end (bed_length={length:g} m)."
        )
    surface = _surface_over(profile, x0, x1)
    floor = float(surface.max()) - c["movable_depth"]
    if floor > float(surface.min()) - 2 * l0 + 1e-9:
        raise ValueError(
            f"movable_depth={c['movable_depth']:g} m leaves less than two grain "
            f"rows where the bed over [{x0:g}, {x1:g}] m is lowest (it falls by "
            f"{float(surface.max() - surface.min()):g} m); deepen movable_depth."
        )
    recess = _recess(c, profile, x0, x1)
    if recess is not None:
        floor = min(
            (floor - j * l0 for j in range(_FLUSH_SPACINGS + 1)),
            key=lambda f: _mismatch(recess, f, l0),
        )
    return x0, x1, floor


def pit_depth(profile, stretch) -> float:
    """The movable bed's pit depth [m] below the highest bed over it (at least
    `movable_depth`; more where `movable_stretch` deepened it under blocks)."""
    x0, x1, floor = stretch
    return float(_surface_over(profile, x0, x1).max()) - floor


def _surface_over(profile, x0: float, x1: float) -> np.ndarray:
    """The bed's heights over [x0, x1] at 64 points and at its knots there (its
    highest and lowest points, which the 64 may miss)."""
    knots = profile.knots[:, 0]
    x = np.concatenate([np.linspace(x0, x1, 64), knots[(knots > x0) & (knots < x1)]])
    return profile.height(x)


# A packed bed's rows rise by sqrt(3)/2 d and the lattice by l0 = d: lowering the
# floor by one spacing moves the rows' tops by (1 - sqrt(3)/2) l0 = 0.134 l0
# against the recess, so within 6 spacings one ends within 0.134 l0 below it.
_FLUSH_SPACINGS = 6


def _recess(c: dict, profile, x0: float, x1: float) -> float | None:
    """The floor level of the blocks' recess where it lies over the movable bed
    [x0, x1] (the blocks then rest on grains), else None."""
    if not c["block_rows"]:
        return None
    if x0 >= profile.protection_end - 1e-9 or x1 <= profile.apron_end + 1e-9:
        return None
    return float(profile.height(0.5 * (profile.apron_end + profile.protection_end)))


def _mismatch(level: float, floor: float, l0: float) -> float:
    """How far below `level` the top of the highest row of a packed bed of
    diameter l0 laid on `floor` ends (each row wholly below `level`)."""
    rise = np.sqrt(3.0) / 2.0 * l0
    rows = np.floor((level - floor - l0) / rise + 1e-9)
    return float(level - (floor + l0 + rows * rise))


def block_sink(c: dict, profile, stretch) -> float:
    """How far the blocks are lowered into their recess [m] so that they rest on
    the packed bed under them (0 without one): the rows' mismatch, below 0.134
    l0 (`movable_stretch` chooses the floor for it)."""
    if stretch is None:
        return 0.0
    x0, x1, floor = stretch
    recess = _recess(c, profile, x0, x1)
    return 0.0 if recess is None else _mismatch(recess, floor, c["spacing"])


def bed_grains(profile, stretch, l0: float) -> np.ndarray:
    """The grains' centres: seed 002's packed bed (`geometry.packed_bed`) of
    diameter l0 filling the pit up to the bed's surface (each grain wholly below
    it); none without a stretch."""
    if stretch is None:
        return np.zeros((0, 2))
    x0, x1, floor = stretch
    top = float(_surface_over(profile, x0, x1).max())
    packed = geometry.packed_bed([x0, floor], [x1, top], l0)
    below = packed[:, 1] + 0.5 * l0 <= _lowest_over(profile, packed[:, 0], 0.5 * l0)
    return packed[below]


def _lowest_over(profile, x: np.ndarray, half: float) -> np.ndarray:
    """The lowest bed surface over [x - half, x + half] for each x (a vertical
    face inside the span counts with its lower end, one at its ends not), so
    that a grain under the surface is wholly under it, not cut by a step such as
    the last block's downstream face."""
    tiny = 1e-9 * half
    lowest = np.minimum(
        profile.height(x - half + tiny), profile.height(x + half - tiny)
    )
    kx, kz = profile.knots[:, 0], profile.knots[:, 1]
    inside = (kx[None, :] > x[:, None] - half + tiny) & (
        kx[None, :] < x[:, None] + half - tiny
    )
    knots = np.min(np.where(inside, kz[None, :], np.inf), axis=1)
    return np.minimum(lowest, knots) + tiny


def clear_of(points: np.ndarray, grains: np.ndarray, distance: float) -> np.ndarray:
    """Which `points` lie at least `distance` from every grain (the water laid
    over a packed bed's staircase)."""
    keep = np.ones(len(points), bool)
    if not len(grains) or not len(points):
        return keep
    near = (points[:, 0] > grains[:, 0].min() - distance) & (
        points[:, 0] < grains[:, 0].max() + distance
    )
    near &= points[:, 1] < grains[:, 1].max() + distance
    index = np.nonzero(near)[0]
    for start in range(0, len(index), 2048):
        chunk = points[index[start : start + 2048]]
        d2 = np.min(np.sum((chunk[:, None] - grains[None]) ** 2, axis=-1), axis=1)
        keep[index[start : start + 2048]] = d2 >= distance**2 * (1 - 1e-9)
    return keep


def _stiffness(c: dict):
    """The grains' stiffness: the `stiffness` setting, or where it is None seed
    002's rule at the step with the explicit solver (its flume runs: a bed under
    a flow, whose grains meet at the flow's speeds, not at free fall; one DEM
    sub-step), the overlap rule of `add_grains` at a semi-implicit step (where
    the rule is too soft to carry a bed)."""
    if c["stiffness"] is not None:
        return c["stiffness"]
    return "rule" if c["solver"] == "explicit" else None


def add_bed_grains(c: dict, stretch, first: int, count: int, case: tuple) -> tuple:
    """The (scene, params, state, probes) of `case` with its particles
    [first, first + count) made DEM grains attached to the bed (seed 002 §5.5),
    feeling no flow until `release_time` (`Params.grains.release_time`), and
    the scour hole's probes:
    `scour_depth` and `scour_length` (`BedLowering`)."""
    if not count:
        return case
    scene, params, state, probes = case
    mask = np.zeros(scene.capacity, bool)
    mask[first : first + count] = True
    scene, params, state = add_grains(
        scene,
        params,
        state,
        mask,
        friction=c["friction"],
        restitution=c["restitution"],
        density=c["grain_density"],
        stiffness=_stiffness(c),
        lift=c["lift"],
        rolling=c["rolling"],
        contact_capacity=c["contact_capacity"],
        substeps=c["substeps"],
        on_fluid=c["on_fluid"],
        attached=mask,
        release_time=c["release_time"],
    )
    x0, x1, floor = stretch
    l0 = c["spacing"]
    bins = max(1, math.floor((x1 - x0) / (2 * l0)))
    kwargs = {"x0": x0, "width": (x1 - x0) / bins, "floor": floor, "diameter": l0}
    hole = tuple(
        BedLowering(name, bins=bins, measure=name.split("_")[1], **kwargs)
        for name in ("scour_depth", "scour_length")
    )
    return scene, params, state, probes + hole
