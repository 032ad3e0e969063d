"""Host-side particle geometry on regular lattices (NumPy; never jitted)."""

import math
import os

import numpy as np

from .._types import Kind

# Choice: the device memory a run needs per particle slot, estimated from the
# arrays of one step (state, neighbour lists and pair arrays of about 2 x the
# lattice neighbour count, the pressure solve's vectors): 2 KiB in 2-D, 8 KiB in
# 3-D. An estimate for refusing absurd sizes early, not a measurement.
BYTES_PER_PARTICLE = {2: 2 << 10, 3: 8 << 10}


def particle_limit(dim: int) -> int:
    """The most lattice points one `block` may hold: `JAXMPS_MAX_PARTICLES` if set,
    else as many as the machine's physical memory holds at `BYTES_PER_PARTICLE`."""
    setting = os.environ.get("JAXMPS_MAX_PARTICLES")
    if setting:
        try:
            limit = float(setting)
        except ValueError:
            limit = math.nan
        if not (math.isfinite(limit) and limit >= 1):
            raise ValueError(
                f"JAXMPS_MAX_PARTICLES={setting!r} is not a number of particles "
                "(a whole number >= 1); unset it to use the machine's memory."
            )
        return int(limit)
    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        memory = 64 << 30
    return memory // BYTES_PER_PARTICLE.get(dim, BYTES_PER_PARTICLE[3])


def _check_size(counts: np.ndarray, spacing: float) -> None:
    """Refuse a lattice too large to run, before allocating it (ValueError naming
    the count, the memory and `spacing`)."""
    dim = len(counts)
    # As a float (inf beyond its range): a tiny spacing gives counts whose product
    # no float holds.
    total = math.prod(float(c) for c in counts)
    limit = particle_limit(dim)
    if total > limit:
        per = BYTES_PER_PARTICLE.get(dim, BYTES_PER_PARTICLE[3])
        raise ValueError(
            f"spacing={spacing:g} m asks for {total:.3g} particles in one block "
            f"(about {total * per / 2**30:.3g} GiB to run), above the limit of "
            f"{limit:.3g} (the machine's memory, or JAXMPS_MAX_PARTICLES); raise "
            f"`spacing` (x{(total / limit) ** (1 / dim):.2g} at least) or shrink "
            "the scene's lengths."
        )


def block(lower, upper, spacing: float) -> np.ndarray:
    """Lattice points filling the box [lower, upper]: centres at lower + (i + 1/2) l0.

    The box extents must be whole multiples of the spacing (within 1e-6 l0).
    """
    lower = np.asarray(lower, dtype=np.float64)
    upper = np.asarray(upper, dtype=np.float64)
    extent = (upper - lower) / spacing
    if not np.all(np.isfinite(extent)):
        raise ValueError(
            f"Box {lower.tolist()}..{upper.tolist()} at spacing {spacing} is not "
            "finite; change the size or `spacing`."
        )
    _check_size(np.maximum(np.rint(extent), 0), spacing)
    counts = np.rint(extent).astype(int)
    if np.any(np.abs(extent - counts) > 1e-6) or np.any(counts < 1):
        raise ValueError(
            f"Box {lower.tolist()}..{upper.tolist()} is not a whole number of spacings "
            f"{spacing}; change the size or `spacing`."
        )
    axes = [lower[a] + (np.arange(c) + 0.5) * spacing for a, c in enumerate(counts)]
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=-1)


def layers_for(r_e_over_l0: float) -> int:
    """Number of boundary layers (pressure wall + dummy) giving a wall particle a
    full neighbourhood: ceil(r_e / l0). Three for r_e = 2.1 l0 (seed 000 §2.10)."""
    return int(np.ceil(r_e_over_l0 - 1e-9))


def tank(
    inner_lower,
    inner_upper,
    spacing: float,
    layers: int = 3,
    wall_layers: int = 1,
    open_top: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Wall and dummy particles around the box [inner_lower, inner_upper].

    The first `wall_layers` shells outside the inner faces are pressure walls
    (`Kind.WALL`), the remaining `layers - wall_layers` are dummies (`Kind.DUMMY`).
    The last axis is vertical; with `open_top` there is no lid.

    Returns:
        positions (m, d) and kinds (m,).
    """
    inner_lower = np.asarray(inner_lower, dtype=np.float64)
    inner_upper = np.asarray(inner_upper, dtype=np.float64)
    if not 1 <= wall_layers <= layers:
        raise ValueError("Need 1 <= wall_layers <= layers.")
    pad = layers * spacing
    lower = inner_lower - pad
    upper = inner_upper + pad
    if open_top:
        upper[-1] = inner_upper[-1]
    pts = block(lower, upper, spacing)
    below = np.maximum(inner_lower - pts, 0.0)
    above = np.maximum(pts - inner_upper, 0.0)
    outside = np.max(np.maximum(below, above), axis=1)
    keep = outside > 0
    layer = np.rint(outside[keep] / spacing - 0.5).astype(int)
    kinds = np.where(layer < wall_layers, int(Kind.WALL), int(Kind.DUMMY))
    return pts[keep], kinds.astype(np.int32)


def plate(
    lower, upper, spacing: float, wall_layers: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """A solid plate (or any solid block) filling the box [lower, upper]: a shell
    `wall_layers` deep of pressure walls (`Kind.WALL`) around a core of dummies
    (`Kind.DUMMY`).

    Fluid may touch it from every side: each face has its pressure walls and the
    dummies behind them, so a thin plate is at least 2 `wall_layers` + 1 particles
    thick (seed 001 §4.1: wall / dummy / wall, the dummy layer capped by walls at
    the ends). With r_e <= 2.5 l0 (the default schemes) the water on the two
    faces of a 3-layer plate, 4 l0 apart, does not interact; a wider r_e reaches
    through it to the far face's walls (a thicker plate avoids that).

    The box extents must be whole multiples of `spacing`. Where the plate meets a
    tank's wall, drop its particles that overlap the wall's (`remove_overlaps`)
    and it joins the wall.

    Returns:
        positions (m, d) and kinds (m,).
    """
    if not (isinstance(wall_layers, (int, np.integer)) and wall_layers >= 1):
        raise ValueError(
            f"wall_layers must be a whole number >= 1, got {wall_layers!r}."
        )
    lower = np.asarray(lower, dtype=np.float64)
    upper = np.asarray(upper, dtype=np.float64)
    pts = block(lower, upper, spacing)
    counts = np.rint((upper - lower) / spacing).astype(int)
    thinnest = int(counts.min())
    if thinnest < 2 * wall_layers + 1:
        raise ValueError(
            f"A plate {thinnest} particle(s) thick has no dummy core: with "
            f"wall_layers={wall_layers} it needs {2 * wall_layers + 1} (thickness "
            f"{(2 * wall_layers + 1) * spacing:g} m at spacing {spacing:g}); make the "
            "box thicker or `spacing` smaller."
        )
    inside = np.minimum(pts - lower, upper - pts).min(axis=1)
    layer = np.rint(inside / spacing - 0.5).astype(int)
    kinds = np.where(layer < wall_layers, int(Kind.WALL), int(Kind.DUMMY))
    return pts, kinds.astype(np.int32)


def remove_overlaps(
    points: np.ndarray, others: np.ndarray, spacing: float
) -> np.ndarray:
    """Drop points closer than spacing/2 to any point of `others` (host, O(n m))."""
    if len(points) == 0 or len(others) == 0:
        return points
    keep = np.ones(len(points), dtype=bool)
    for start in range(0, len(points), 4096):
        chunk = points[start : start + 4096]
        d2 = np.min(np.sum((chunk[:, None] - others[None]) ** 2, axis=-1), axis=1)
        keep[start : start + 4096] = d2 > (0.5 * spacing) ** 2
    return points[keep]


def packed_bed(lower, upper, diameter: float) -> np.ndarray:
    """Centres of spheres (2-D: discs) of `diameter` d in the closest packing of
    seed 002's bed (Fig. 3.14b): rows d apart along x, sqrt(3)/2 d apart in y,
    every other row shifted by d/2, filling [lower, upper] so that each sphere
    lies inside the box (2-D only: the bed seen in the flume's plane).

    With d = l0 its number density is 1.25 n0 of the square lattice (seed 002
    §2.9: n_s0 / n0 = 1.25, at r_e = 2.1 l0).
    """
    lower = np.asarray(lower, dtype=np.float64)
    upper = np.asarray(upper, dtype=np.float64)
    if lower.shape != (2,) or upper.shape != (2,):
        raise ValueError("packed_bed builds a 2-D bed: give lower and upper as (x, y).")
    if not diameter > 0 or np.any(upper - lower < diameter):
        raise ValueError(
            f"A packed bed of diameter {diameter} needs a box at least one diameter "
            f"wide and tall, got {lower.tolist()}..{upper.tolist()}."
        )
    rise = math.sqrt(3.0) / 2.0 * diameter
    rows = int(math.floor((upper[1] - lower[1] - diameter) / rise + 1e-9)) + 1
    centres = []
    for k in range(rows):
        start = lower[0] + 0.5 * diameter * (2 if k % 2 else 1)
        x = np.arange(start, upper[0] - 0.5 * diameter + 1e-9 * diameter, diameter)
        y = lower[1] + 0.5 * diameter + k * rise
        centres.append(np.stack([x, np.full_like(x, y)], axis=-1))
    return np.concatenate(centres)
