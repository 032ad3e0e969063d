"""The flume's bed: a groundsill (crest, step, apron), the reach below it with an
optional scour hole, a transition down to the lowered bed, and the wall and
dummy particles that line it (host-side NumPy)."""

import dataclasses

import numpy as np

from .. import geometry
from .._types import Kind


@dataclasses.dataclass(frozen=True)
class BedProfile:
    """The bed's surface z_b(x) as a polyline through `knots` (x, z), x
    non-decreasing: two knots at one x are a vertical face (a step). The crest
    is at z = 0; the inflow enters on it at x = 0.

    `apron_end` is where the reach below the groundsill starts (the blocks and the
    movable bed are laid from there), `recess` the stretch whose bed is lowered
    by the blocks' height (the blocks sit in it, their tops level with the
    apron)."""

    knots: np.ndarray  # (k, 2)
    apron_end: float
    protection_end: float

    def height(self, x: np.ndarray | float) -> np.ndarray | float:
        """z_b at `x` (not on a vertical face's own x)."""
        return np.interp(x, self.knots[:, 0], self.knots[:, 1])

    def filled(self, x: np.ndarray) -> np.ndarray:
        """The bed with its hollows filled to their brims (the blocks' recess, a
        scour hole): min(highest bed upstream, highest bed downstream)."""
        x = np.asarray(x, np.float64)
        kx, kz = self.knots[:, 0], self.knots[:, 1]
        here = self.height(x)
        from_left = np.maximum.accumulate(kz)
        from_right = np.maximum.accumulate(kz[::-1])[::-1]
        last = np.clip(np.searchsorted(kx, x, side="right") - 1, 0, len(kx) - 1)
        first = np.clip(np.searchsorted(kx, x, side="left"), 0, len(kx) - 1)
        left = np.maximum(from_left[last], here)
        right = np.maximum(from_right[first], here)
        return np.minimum(left, right)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Each point's Euclidean distance to the polyline."""
        return _distance(points, self.knots)

    @property
    def lowest(self) -> float:
        return float(self.knots[:, 1].min())


def _distance(points: np.ndarray, knots: np.ndarray) -> np.ndarray:
    a, b = knots[:-1], knots[1:]
    ab = b - a
    length2 = np.maximum(np.sum(ab * ab, axis=1), 1e-300)
    out = np.full(len(points), np.inf)
    for start in range(0, len(points), 8192):
        p = points[start : start + 8192, None, :]
        t = np.clip(np.sum((p - a) * ab, axis=-1) / length2, 0.0, 1.0)
        nearest = a + t[..., None] * ab
        out[start : start + 8192] = np.min(np.linalg.norm(p - nearest, axis=-1), axis=1)
    return out


def optional(value, l0: float) -> float:
    """A length rounded to whole spacings, 0 for 0 (or None)."""
    if not value:
        return 0.0
    return max(1, round(float(value) / l0)) * l0


def bed_profile(c: dict, length: float, start: float) -> BedProfile:
    """The profile of the flume settings `c` (lengths already whole spacings),
    from x = `start` (under the inflow) to `length`:

    crest (z = 0) for `crest_length` -> a vertical step down by `step_height` ->
    the apron for `apron_length` -> the reach at the apron's level, whose first
    `block_rows` rows of blocks lie in a recess `block_height` deep and whose
    next `scour_length` holds a scour hole -> the transition falling by
    `bed_lowering` over `transition_length` (vertical if 0) -> the lowered bed
    to `length`."""
    step, drop = c["step_height"], c["bed_lowering"]
    crest = length if c["crest_length"] is None else c["crest_length"]
    knots = [(start, 0.0), (crest, 0.0)]
    apron = -step
    if step:
        knots.append((crest, apron))
    x = crest + c["apron_length"]
    apron_end = x
    protection = c["block_rows"] * (c["block_length"] + c["block_gap"])
    if protection:
        # The rows start one gap below the apron; the last one's downstream face
        # rests against the bed beyond (or faces the scour hole).
        knots += [(x, apron), (x, apron - c["block_height"])]
        x += protection
        knots.append((x, apron - c["block_height"]))
        exposure = c["scour_exposure"] if c["scour_length"] else 0.0
        knots.append((x, apron - min(exposure, c["block_height"])))
    protection_end = x
    if c["scour_length"]:
        if not protection:
            knots.append((x, apron - c["scour_exposure"]))
        centre = c["scour_centre"]
        if centre is None:
            centre = 0.5 * c["scour_length"]
        knots.append((x + centre, apron - c["scour_depth"]))
        x += c["scour_length"]
        knots.append((x, apron))
    reach_end = apron_end + c["reach_length"]
    knots.append((reach_end, apron))
    x = reach_end + c["transition_length"]
    knots.append((x, apron - drop))
    knots.append((length, apron - drop))
    knots = np.asarray(knots, np.float64)
    return BedProfile(_merged(knots), apron_end, protection_end)


def _merged(knots: np.ndarray) -> np.ndarray:
    """The knots without repeats (a zero-length segment)."""
    keep = np.ones(len(knots), bool)
    keep[1:] = np.any(np.abs(np.diff(knots, axis=0)) > 1e-12, axis=1)
    return knots[keep]


def check_lengths(c: dict, length: float) -> None:
    """The groundsill's pieces fit on the bed and the hole in the reach
    (ValueError naming the settings)."""
    crest = length if c["crest_length"] is None else c["crest_length"]
    pieces = crest + c["apron_length"] + c["reach_length"] + c["transition_length"]
    if pieces > length + 1e-9:
        raise ValueError(
            f"crest_length + apron_length + reach_length + transition_length = "
            f"{pieces:g} m exceeds bed_length={length:g} m; lengthen bed_length or "
            "shorten the pieces."
        )
    if c["crest_length"] is None and (
        c["step_height"] or c["apron_length"] or c["reach_length"]
    ):
        raise ValueError(
            "step_height, apron_length and reach_length shape the bed below a "
            "groundsill; give its crest_length too (where the step is, from the "
            "inflow)."
        )
    protection = c["block_rows"] * (c["block_length"] + c["block_gap"])
    if protection + c["scour_length"] > c["reach_length"] + 1e-9:
        raise ValueError(
            f"the blocks ({protection:g} m) and the scour hole (scour_length="
            f"{c['scour_length']:g} m) must fit in reach_length="
            f"{c['reach_length']:g} m; lengthen reach_length."
        )
    if c["scour_length"]:
        centre = c["scour_centre"]
        if centre is not None and not 0 < centre < c["scour_length"]:
            raise ValueError(
                f"scour_centre={centre:g} m must lie inside the hole, in (0, "
                f"scour_length={c['scour_length']:g})."
            )
        if c["scour_depth"] < c["scour_exposure"]:
            raise ValueError(
                f"scour_depth={c['scour_depth']:g} m is shallower than "
                f"scour_exposure={c['scour_exposure']:g} m at the hole's upstream "
                "end; deepen the hole or lower the exposure."
            )


def bed_particles(
    profile: BedProfile,
    bed_end: float,
    weir: float,
    layers: int,
    l0: float,
    pit=None,
):
    """The lattice points of the bed and of a tail weir `weir` high at its end
    (from `bed_end - layers l0`, with `bed_end` its downstream face), and their
    kinds: those within l0 of the bed's surface (the polyline, with the weir's
    faces) are pressure walls, those within `layers` l0 dummies.

    `pit`: (x0, x1, floor) where the solid is cut away above `floor` (a movable
    bed fills it); its faces line it instead."""
    start = profile.knots[0, 0]
    lowest = min(profile.lowest, pit[2] if pit else 0.0)
    top = max(0.0, profile.knots[-1, 1] + weir)
    z0 = np.floor((lowest - layers * l0) / l0 - 1e-9) * l0
    grid = geometry.block([start, z0], [bed_end, np.ceil(top / l0 - 1e-9) * l0], l0)
    x, z = grid[:, 0], grid[:, 1]
    solid = z < profile.height(x)
    surface = [profile.knots]
    if weir:
        face = bed_end - layers * l0
        end = profile.knots[-1, 1]
        solid |= (x > face) & (z < end + weir)
        surface.append(
            np.array(
                [[face, end], [face, end + weir], [bed_end, end + weir], [bed_end, end]]
            )
        )
    if pit is not None:
        x0, x1, floor = pit
        solid &= ~((x > x0) & (x < x1) & (z > floor))
        surface.append(np.array([[x0, profile.height(x0 - 1e-9 * l0)], [x0, floor]]))
        surface.append(np.array([[x0, floor], [x1, floor]]))
        surface.append(np.array([[x1, floor], [x1, profile.height(x1 + 1e-9 * l0)]]))
    distance = np.min([_distance(grid, s) for s in surface], axis=0)
    if pit is not None:
        # The cut-away solid's own surface is not a wall: only the pit's faces.
        inside = (x > x0) & (x < x1)
        distance = np.where(
            inside, np.min([_distance(grid, s) for s in surface[-3:]], axis=0), distance
        )
    keep = solid & (distance < layers * l0)
    kind = np.where(distance[keep] < l0, int(Kind.WALL), int(Kind.DUMMY))
    return grid[keep], kind.astype(np.int32)


def fill(
    profile: BedProfile, length: float, depth: float, l0: float, level=None
) -> tuple[np.ndarray, np.ndarray]:
    """Lattice points of water `depth` deep over the bed (following it, its
    hollows filled: over the blocks' recess and a scour hole from their brims),
    or up to the height `level` where that is higher, on [0, length]; and each
    one's water depth. Points inside the blocks are for the caller to remove."""
    surface = profile.height(np.asarray([0.0])) + depth
    if level is not None:
        surface = np.maximum(surface, level)
    grid = geometry.block(
        [0.0, np.floor(profile.lowest / l0 - 1e-9) * l0],
        [length, np.ceil(float(surface.max()) / l0 - 1e-9) * l0],
        l0,
    )
    bed = profile.height(grid[:, 0])
    top = profile.filled(grid[:, 0]) + depth
    if level is not None:
        top = np.maximum(top, level)
    keep = (grid[:, 1] > bed) & (grid[:, 1] < top)
    return grid[keep], (top - bed)[keep]


def stored_area(
    profile: BedProfile, length: float, depth: float, weir_level: float | None, l0
) -> float:
    """The water area [m^2] over the bed when every column holds `depth` over
    the filled bed (`BedProfile.filled`), or stands up to `weir_level` where
    that is higher."""
    x = (np.arange(int(round(length / l0))) + 0.5) * l0
    bed = profile.height(x)
    surface = profile.filled(x) + depth
    if weir_level is not None:
        surface = np.maximum(surface, weir_level)
    return float(np.sum(np.maximum(surface - bed, 0.0)) * l0)
