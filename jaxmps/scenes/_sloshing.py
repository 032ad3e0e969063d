"""Standing waves and shaken tanks (seed 001 §3.2-3.3)."""

import dataclasses
import math

import equinox as eqx
import numpy as np

from .. import geometry
from .._build import make_state
from .._types import Kind
from ..fluid import Harmonic, HarmonicParams, PrescribedMotion
from ._case import Case
from ._common import (
    boundary_layers,
    case_params,
    case_scene,
    resolve,
    setting_length,
    velocity_scale,
    whole,
)
from ._probes import ModeAmplitude, RunUp, StripLevel
from ._wave_tank import RESOLVED_WAVELENGTH


def natural_frequency(length: float, depth: float, mode: int, gravity: float):
    """f_n = (1/2 pi) sqrt(k g tanh(k H)), k = (2n - 1) pi / L: the n-th mode a
    horizontally shaken rectangular tank excites (seed 001 eq. 3.7) [Hz]."""
    k = (2 * mode - 1) * math.pi / length
    return math.sqrt(k * gravity * math.tanh(k * depth)) / (2 * math.pi)


def standing_wave_period(length: float, depth: float, gravity: float) -> float:
    """Linear period of the standing wave eta = A cos(2 pi x / L) cos(omega t) of
    wavelength L: omega^2 = g k tanh(k H), k = 2 pi / L (seed 001 eq. 3.4-3.5)."""
    k = 2 * math.pi / length
    return 2 * math.pi / math.sqrt(gravity * k * math.tanh(k * depth))


def _open_tank(c, length, height):
    """Wall + dummy particles of an open rectangular tank [0, length] x [0, height]."""
    layers = boundary_layers(c)
    return geometry.tank([0.0, 0.0], [length, height], c["spacing"], layers=layers)


STANDING_WAVE = {
    "tank_length": 1.0,
    "tank_height": 0.6,
    "depth": 0.5,
    "amplitude": 0.05,
    "mode_number": 2,
    "plate_depth": None,
    "plate_length": 0.1,
    "plate_walls": "both",
    "gravity": 9.8,
    "spacing": 0.01,
    "dim": 2,
    "t_end": 5.0,
}


def standing_wave(**overrides) -> Case:
    """A standing wave released from rest (seed 001 §3.2): water of mean `depth` in
    a tank of `tank_length`, surface eta0(x) = depth + amplitude cos(m pi x / L),
    m = `mode_number`: 2 (default, the seed's) puts one wavelength in the tank, 1
    half of one, the tank's first sloshing mode (its free decay: the resonance a
    shaken tank of that size has).

    Probes: `eta_centre`, `eta_left`, `eta_right` (strip-volume elevations over
    the two central columns and the three next to each wall) and `mode` (the
    amplitude of the cos(m pi x / L) surface mode from all particles). Linear
    theory: mode = A cos(omega t), period in `config["linear_period"]`.

    `plate_depth`, `plate_length`, `plate_walls`: submerged plates at the side
    walls, as in `sloshing_tank`; the probes then read the still water with the
    plates in it as zero.
    """
    c = resolve("standing_wave", STANDING_WAVE, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("standing_wave is 2-D (dim=2).")
    m = int(c["mode_number"])
    l0 = c["spacing"]
    length, depth = setting_length(c, "tank_length"), setting_length(c, "depth")
    height = setting_length(c, "tank_height")
    amp = float(c["amplitude"])
    wavelength = 2 * length / m
    if wavelength < RESOLVED_WAVELENGTH * l0:
        raise ValueError(
            f"mode_number={m} makes a wave {wavelength:.3g} m long in the "
            f"{length:g} m tank, under {RESOLVED_WAVELENGTH} particle spacings "
            f"({l0:g} m): lower mode_number or refine spacing."
        )
    if not 0 <= amp < min(depth, height - depth):
        raise ValueError(
            f"amplitude={amp} must lie in [0, min(depth, tank_height - depth))."
        )
    grid = geometry.block([0.0, 0.0], [length, height], l0)
    k = m * math.pi / length
    surface = depth + amp * np.cos(k * grid[:, 0])
    fluid = grid[grid[:, 1] < surface]
    walls, wall_kind = _open_tank(c, length, height)
    fluid, walls, wall_kind, plate_centre = _with_plates(
        c, length, depth, fluid, walls, wall_kind
    )
    if plate_centre is not None and plate_centre - 2.5 * l0 < amp:
        raise ValueError(
            f"amplitude={amp:g} m uncovers the plate at plate_depth="
            f"{c['plate_depth']:g} m; release a smaller wave or set the plate deeper."
        )
    scene, params, state = _assemble(c, fluid, walls, wall_kind, height, depth)
    strip = 3 * l0
    # Whole columns at the centre: the two beside it when it lies on a column
    # boundary (an even count), else the three around the middle one.
    centre = (2 if round(length / l0) % 2 == 0 else 3) * l0
    probes = (
        StripLevel("eta_centre", 0.5 * length, centre, l0, depth),
        StripLevel("eta_left", 0.5 * strip, strip, l0, depth),
        StripLevel("eta_right", length - 0.5 * strip, strip, l0, depth),
        ModeAmplitude("mode", k, length, l0),
    )
    if plate_centre is not None:
        still = geometry.block([0.0, 0.0], [length, depth], l0)
        probes = _at_rest(probes, still[_apart(still, walls, l0)], l0)
    config = {
        **c,
        "mode_number": m,
        "tank_length": length,
        "depth": depth,
        "plate_centre_depth": plate_centre,
        "linear_period": standing_wave_period(2 * length / m, depth, c["gravity"]),
    }
    return Case(
        name="standing_wave",
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=float(c["t_end"]),
        config=config,
    )


def _assemble(c, fluid, walls, wall_kind, height, depth, motion=None):
    l0 = c["spacing"]
    position = np.concatenate([fluid, walls])
    kind = np.concatenate(
        [np.full(len(fluid), int(Kind.FLUID), np.int32), wall_kind]
    ).astype(np.int32)
    layers = 3
    travel = 0.0 if motion is None else abs(float(c["amplitude"]))
    lower = position.min(axis=0) - (layers * l0 + travel)
    upper = position.max(axis=0) + layers * l0 + travel
    upper[-1] = height + 0.5 * height
    scene = case_scene(c, position, (lower, upper), kind)
    # Velocity scale of the Courant rule: the long-wave speed sqrt(g H) (the wave
    # and sloshing motions stay well below the dam-break scale sqrt(2 g H)).
    params = case_params(c, 2, velocity_scale(0.5 * depth, c["gravity"]))
    if motion is not None:
        motion_params = HarmonicParams(
            amplitude=np.asarray(c["amplitude"], params.dt.dtype),
            frequency=np.asarray(c["frequency"], params.dt.dtype),
        )
        moving = tuple(range(len(fluid), len(position)))
        law = PrescribedMotion(particles=moving, axis=(1.0, 0.0), law=motion)
        scene = eqx.tree_at(lambda s: s.motion, scene, law, is_leaf=lambda x: x is None)
        params = eqx.tree_at(
            lambda p: p.motion, params, motion_params, is_leaf=lambda x: x is None
        )
    return scene, params, make_state(scene, position, kind)


SLOSHING_TANK = {
    "tank_length": 0.5,
    "tank_height": 0.6,
    "depth": 0.3,
    "amplitude": 2.0e-3,
    "frequency": 1.220419,
    "settle": 2.0,
    "slope": 0.0,  # 0: rectangular; else horizontal run per unit rise
    "bottom_width": 0.3,
    "slope_wall": "staircase",
    "plate_depth": None,
    "plate_length": 0.1,
    "plate_walls": "both",
    "gravity": 9.8,
    "spacing": 0.01,
    "dim": 2,
    "t_end": 20.0,
}


def sloshing_tank(**overrides) -> Case:
    """A tank shaken horizontally, x = x0 + A sin(2 pi f (t - settle)) after the
    water settles (seed 001 §3.3).

    Rectangular (default): `tank_length` 0.5 m, `depth` 0.3 m (seed 001 §3.3.1;
    linear resonances 1.2204 and 2.1631 Hz, see `natural_frequency`). With `slope`
    > 0 (e.g. 1.5, seed 001 §3.3.2): a vertical left wall, a flat bottom of
    `bottom_width` and a right wall rising 1 : `slope`, `depth` 0.5 m is the
    Tomita (2016) tank; its slope wall is a lattice staircase
    (`slope_wall="staircase"`) or, as in seed 001, a diagonal row of wall
    particles with dummies stacked vertically (`"type1"`) or normal to the slope
    (`"type2"`); see `_sloped_tank`.

    Submerged plates (seed 001 §4, Urata 2009): `plate_depth` (m below the
    still surface; None, the default: none), `plate_length` (m out from the
    wall, 0.1) and `plate_walls` (both, left, right; the sloped tank: left)
    put a three-layer plate (wall / dummy / wall, `geometry.plate`) at the
    side walls, moving with the tank; see `_plates`. Urata's tank:
    `tank_length=0.45, depth=0.25` (linear f1 1.2769 Hz).

    Probes: `eta_left` and `eta_right` (strip-volume elevation over 3 l0 next to
    each wall, following the tank); rectangular tank: `mode1`, `mode2` (amplitude
    of the surface modes cos(k x), k = pi/L and 3 pi/L, that the shaking
    excites; see `ModeAmplitude`); sloped tank: `run_up` (the seed's run-up R:
    highest fluid within 1.5 l0 of the slope, above still water; `eta_left` is its
    side-wall height H).
    """
    specific = dict(SLOSHING_TANK)
    if overrides.get("slope"):
        specific.update(depth=0.5, tank_height=0.85, frequency=0.64, amplitude=7.5e-3)
    c = resolve("sloshing_tank", specific, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("sloshing_tank is 2-D (dim=2).")
    l0 = c["spacing"]
    depth, height = setting_length(c, "depth"), setting_length(c, "tank_height")
    if not depth < height:
        raise ValueError(
            f"depth={depth:g} m fills the tank (tank_height={height:g} m): the "
            "water must lie below the walls' top; lower depth or raise tank_height."
        )
    if not float(c["settle"]) >= 0:
        raise ValueError("settle must be >= 0 s.")
    strip = 3 * l0
    law = Harmonic(start=float(c["settle"]))
    if not c["slope"]:
        length = setting_length(c, "tank_length")
        fluid = geometry.block([0.0, 0.0], [length, depth], l0)
        walls, wall_kind = _open_tank(c, length, height)
        scene, params, state, fluid, frame, plate_centre = _shaken(
            c, (fluid, walls, wall_kind), length, height, depth, law
        )
        probes = (
            StripLevel("eta_left", 0.5 * strip, strip, l0, depth, **frame),
            StripLevel("eta_right", length - 0.5 * strip, strip, l0, depth, **frame),
            *(
                ModeAmplitude(
                    f"mode{m}", (2 * m - 1) * math.pi / length, length, l0, **frame
                )
                for m in (1, 2)
            ),
        )
        config = {
            **c,
            "tank_length": length,
            "depth": depth,
            "resonances": [
                natural_frequency(length, depth, m, c["gravity"]) for m in (1, 2)
            ],
        }
    else:
        s, base = float(c["slope"]), setting_length(c, "bottom_width")
        if not s > 0:
            raise ValueError("slope must be positive (horizontal run per unit rise).")
        length = whole(base + s * height, l0)
        particles = _sloped_tank(c, base, s, length, height, depth)
        scene, params, state, fluid, frame, plate_centre = _shaken(
            c, particles, length, height, depth, law, slope=(base, s)
        )
        probes = (
            StripLevel("eta_left", 0.5 * strip, strip, l0, depth, **frame),
            RunUp(
                "run_up", frame["anchor"], frame["anchor_x"], base, s, 1.5 * l0, depth
            ),
        )
        config = {**c, "depth": depth, "bottom_width": base}
    if plate_centre is not None:
        probes = _at_rest(probes, fluid, l0)  # the tank starts at rest
    config["plate_centre_depth"] = plate_centre
    t_end = float(c["t_end"])
    return Case("sloshing_tank", scene, params, state, probes, t_end, config)


def _shaken(c, particles, length, height, depth, law, slope=None):
    """The shaken tank's scene, params and state from its (water, walls, wall
    kinds), with the `plate_*` settings' plates; also the water (less the
    plates'), the probes' frame (the left wall particle at mid-depth, which
    every wall moves with) and the plates' middle-layer depth (None: none)."""
    l0 = c["spacing"]
    fluid, walls, wall_kind, plate_centre = _with_plates(
        c, length, depth, *particles, slope=slope
    )
    scene, params, state = _assemble(
        c, fluid, walls, wall_kind, height, depth, motion=law
    )
    wall_x = -0.5 * l0  # the left wall's pressure layer
    anchor = len(fluid) + _nearest(walls, [wall_x, 0.5 * depth])
    frame = dict(anchor=anchor, anchor_x=wall_x)
    return scene, params, state, fluid, frame, plate_centre


def _plates(c: dict, length: float, depth: float, walls, slope=None):
    """Submerged horizontal plates (seed 001 §4.1, Urata 2009) at the tank's side
    walls, by the settings `plate_depth` (m below the still surface of the
    plate's middle (dummy) layer, as in seed 001; None: no plates),
    `plate_length` (m out from the wall) and `plate_walls` (both, left, right):
    each plate three layers thick (`geometry.plate`: wall / dummy / wall), its
    middle layer on the lattice row nearest `plate_depth` (the deeper of two
    equally near), joined to the tank's wall.

    `slope`: (bottom width, run per unit rise) of a sloped tank, whose plates go
    on its vertical (left) wall only and must end clear of the slope.

    Returns the plates' particles and kinds (empty without plates) and the depth
    of their middle layer (None without plates).
    """
    none = np.zeros((0, 2)), np.zeros(0, np.int32), None
    if c["plate_depth"] is None:
        return none
    l0 = c["spacing"]
    side = c["plate_walls"]
    if slope is not None and side != "left":
        raise ValueError(
            "The sloped tank takes plates on its vertical (left) wall only: set "
            "plate_walls=left."
        )
    span = setting_length(c, "plate_length")
    centre = depth - float(c["plate_depth"])
    row = math.ceil(centre / l0 - 1.0 - 1e-6)  # middle layer at (row + 1/2) l0
    bottom, top = (row - 1) * l0, (row + 2) * l0
    if not (bottom >= l0 * (1 - 1e-9) and top <= depth - l0 * (1 - 1e-9)):
        raise ValueError(
            f"plate_depth={c['plate_depth']:g} m puts a plate {3 * l0:g} m thick "
            f"(three layers at spacing {l0:g}) with no water above or below it in "
            f"{depth:g} m of water; choose plate_depth from {2 * l0:g} to below "
            f"{depth - 2 * l0:g} m, or a smaller spacing."
        )
    if span < l0 or span > (0.5 if side == "both" else 1.0) * length - 2 * l0:
        raise ValueError(
            f"plate_length={c['plate_length']:g} m must be at least one spacing and "
            "leave the water two spacings between the plate's end and the "
            f"{'other plate' if side == 'both' else 'far wall'} in a "
            f"{length:g} m tank."
        )
    reach = boundary_layers(c) * l0
    boxes = []
    if side in ("both", "left"):
        boxes.append(([-reach, bottom], [span, top]))
    if side in ("both", "right"):
        boxes.append(([length - span, bottom], [length + reach, top]))
    parts = [geometry.plate(lo, hi, l0) for lo, hi in boxes]
    points = np.concatenate([p for p, _ in parts])
    kinds = np.concatenate([k for _, k in parts])
    if slope is not None and span + 2 * l0 > slope[0] + slope[1] * bottom:
        raise ValueError(
            f"plate_length={c['plate_length']:g} m leaves less than two spacings "
            f"of water between the plate and the slope at plate_depth="
            f"{c['plate_depth']:g} m; shorten the plate."
        )
    keep = _apart(points, walls, l0)
    return points[keep], kinds[keep], depth - (row + 0.5) * l0


def _with_plates(c, length, depth, fluid, walls, wall_kind, slope=None):
    """The tank's water, walls and kinds with the `plate_*` settings' plates
    (`_plates`) among the walls and out of the water, and the plates' middle-layer
    depth (None without plates)."""
    plates, plate_kind, centre = _plates(c, length, depth, walls, slope)
    if centre is None:
        return fluid, walls, wall_kind, None
    fluid = fluid[_apart(fluid, plates, c["spacing"])]
    walls = np.concatenate([walls, plates])
    wall_kind = np.concatenate([wall_kind, plate_kind]).astype(np.int32)
    return fluid, walls, wall_kind, centre


def _at_rest(probes, still, spacing):
    """`probes` reading zero for the water at rest `still` (its particles): the
    strip levels' still depth and the mode amplitudes' still sum taken from it,
    so that plates in the water do not read as a lower surface."""
    out = []
    for probe in probes:
        x = still[:, 0]
        if isinstance(probe, StripLevel):
            inside = np.abs(x - probe.x) < 0.5 * probe.width
            level = np.sum(inside) * spacing**2 / probe.width
            probe = dataclasses.replace(probe, still_depth=float(level))
        elif isinstance(probe, ModeAmplitude):
            total = np.sum(np.cos(probe.wave_number * x)) * spacing**2
            probe = dataclasses.replace(probe, still=float(2 / probe.length * total))
        out.append(probe)
    return tuple(out)


def _apart(points, others, spacing):
    """Mask of `points` farther than spacing / 2 from every point of `others`."""
    if len(others) == 0:
        return np.ones(len(points), bool)
    d2 = np.min(np.sum((points[:, None] - others[None]) ** 2, axis=-1), axis=1)
    return d2 > (0.5 * spacing) ** 2


def _nearest(points, target) -> int:
    return int(np.argmin(np.linalg.norm(points - np.asarray(target), axis=1)))


def _sloped_tank(c: dict, base: float, s: float, length: float, height, depth):
    """Water, walls and wall kinds of the sloped tank: a vertical left wall, a flat
    bottom of `base`, and a right wall rising 1 : `s`, by the `slope_wall`
    setting:

    - "staircase": lattice particles within l0 below the slope are its wall
      particles, those within the boundary's depth behind them its dummies;
    - "type1", "type2" (seed 001 §3.3.2, Fig. 3.10): wall particles in point
      contact along a line 0.5 l0 below the slope, with dummies stacked
      vertically under each ("type1", as under the bottom: a denser wall that
      pushes harder but wedges no fluid) or normal to the slope ("type2": the
      other walls' number density).
    """
    l0 = c["spacing"]
    layers = boundary_layers(c)
    walls, wall_kind = _open_tank(c, length, height)
    keep = walls[:, 0] < base  # left wall and the bed under the flat bottom
    walls, wall_kind = walls[keep], wall_kind[keep]
    if c["slope_wall"] == "staircase":
        grid = geometry.block(
            [base - 2 * layers * l0, -layers * l0], [length, height], l0
        )
        rise = (grid[:, 0] - base) / s  # slope surface height above the bed
        dist = (rise - grid[:, 1]) / math.sqrt(1 + 1 / s**2)
        slab = (dist > 0) & (dist < layers * l0) & (grid[:, 0] >= base)
        slab |= (grid[:, 1] < 0) & (grid[:, 0] >= base) & (dist < layers * l0)
        slope_walls = grid[slab]
        slope_kind = np.where(dist[slab] < l0, Kind.WALL, Kind.DUMMY)
    else:
        norm = math.sqrt(1 + s * s)
        along = np.array([s, 1.0]) / norm
        into = np.array([1.0, -s]) / norm  # normal, into the wall
        count = int((height + l0) * norm / l0) + 1
        line = np.array([base, 0.0]) + 0.5 * l0 * into
        line = line + l0 * np.arange(count)[:, None] * along
        behind = into if c["slope_wall"] == "type2" else np.array([0.0, -1.0])
        steps = l0 * np.arange(1, layers)[:, None, None] * behind
        dummies = (line[None] + steps).reshape(-1, 2)
        slope_walls = np.concatenate([line, dummies])
        slope_kind = np.concatenate(
            [np.full(len(line), Kind.WALL), np.full(len(dummies), Kind.DUMMY)]
        )
    walls = np.concatenate([walls, slope_walls])
    wall_kind = np.concatenate([wall_kind, slope_kind]).astype(np.int32)
    fluid = geometry.block([0.0, 0.0], [length, depth], l0)
    above = fluid[:, 1] > (fluid[:, 0] - base) / s + 0.5 * l0
    return fluid[above | (fluid[:, 0] < base)], walls, wall_kind
