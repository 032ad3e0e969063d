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
    naming the settings where it does not fit on the bed)."""
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
    x = np.linspace(x0, x1, 64)
    surface = profile.height(x)
    floor = float(surface.max()) - c["movable_depth"]
    if floor > float(surface.min()) - 2 * l0 + 1e-9:
        raise ValueError(
            f"movable_depth={c['movable_depth']:g} m leaves less than two grain "
            f"rows where the bed over [{x0:g}, {x1:g}] m is lowest (it falls by "
            f"{float(surface.max() - surface.min()):g} m); deepen movable_depth."
        )
    return x0, x1, floor


def bed_grains(profile, stretch, l0: float) -> np.ndarray:
    """The grains' centres: seed 002's packed bed (`geometry.packed_bed`) of
    diameter l0 filling the pit up to the bed's surface (each grain wholly below
    it); none without a stretch."""
    if stretch is None:
        return np.zeros((0, 2))
    x0, x1, floor = stretch
    top = float(profile.height(np.linspace(x0, x1, 64)).max())
    packed = geometry.packed_bed([x0, floor], [x1, top], l0)
    below = packed[:, 1] + 0.5 * l0 <= profile.height(packed[:, 0]) + 1e-9 * l0
    return packed[below]


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
