"""Wave tank with a piston wave maker (seed 000 §2.11 approach 1)."""

import math

import equinox as eqx
import numpy as np

from .. import geometry
from .._build import make_state
from .._types import Kind
from ..fluid import PrescribedMotion, StrokeParams, Tabulated
from ._case import Case
from ._common import (
    boundary_layers,
    case_params,
    case_scene,
    check_gauge,
    resolve,
    setting_length,
    whole,
)
from ._probes import StripLevel

DEFAULTS = {
    "tank_length": 2.0,
    "depth": 0.1,
    "stroke": 0.03,  # full piston stroke S [m] (peak to peak)
    "wave_period": 0.8,  # [s]
    "ramp_periods": 1.0,  # periods over which the stroke amplitude ramps up
    "end": "wall",  # "wall" or "beach"
    "beach_slope": 5.0,  # beach rises 1 per `beach_slope` horizontally
    "gauge_x": 0.6,  # surface-elevation gauge position from the piston [m]
    "spacing": 0.01,
    "dim": 2,
    "t_end": 3.5,
}


# The shortest wave the tank makes, in particle spacings: a wave must span
# several kernel radii (2.1 l0) to be a wave of the particles at all.
RESOLVED_WAVELENGTH = 8


def linear_wave_number(period: float, depth: float, gravity: float) -> float:
    """k from the dispersion relation omega^2 = g k tanh(k h) (Newton)."""
    omega = 2 * math.pi / period
    k = omega**2 / gravity
    for _ in range(50):
        t = math.tanh(k * depth)
        f = gravity * k * t - omega**2
        df = gravity * t + gravity * k * depth * (1 - t) * (1 + t)  # sech^2 = 1 - t^2
        k -= f / df
    return k


def piston_height_ratio(k: float, depth: float) -> float:
    """Linear piston wave-maker theory: H / S = 2 (cosh 2kh - 1) / (sinh 2kh + 2kh)
    (Dean & Dalrymple 1991, eq. 6.22)."""
    kh2 = 2 * k * depth
    # Divided through by cosh 2kh (whose 1 / cosh = 2 e^-x / (1 + e^-2x) cannot
    # overflow): deep water tends to 2 without inf / inf.
    e = math.exp(-kh2)
    sech = 2 * e / (1 + e * e)
    return 2 * (1 - sech) / (math.tanh(kh2) + kh2 * sech)


def _wave_number(period: float, depth: float, gravity: float, l0: float) -> float:
    """The linear wave number of `period` in `depth`; a wave shorter than
    RESOLVED_WAVELENGTH spacings is refused, naming `wave_period`."""
    k = linear_wave_number(period, depth, gravity)
    if 2 * math.pi / k < RESOLVED_WAVELENGTH * l0:
        raise ValueError(
            f"wave_period={period:g} s makes waves {2 * math.pi / k:.3g} m long, "
            f"under {RESOLVED_WAVELENGTH} particle spacings ({l0:g} m): lengthen "
            "wave_period or refine spacing."
        )
    return k


def _check_stroke(stroke: float, ratio: float, depth: float, height: float) -> None:
    """Refuse a stroke whose linear waves would overtop the tank: crests of half
    the wave height above the still water, over the freeboard `height - depth`
    (the walls stand 1.6 depths high), naming `stroke` and the largest it takes."""
    freeboard = height - depth
    if ratio * stroke > 2 * freeboard:
        raise ValueError(
            f"stroke={stroke:g} m makes linear waves {ratio * stroke:.3g} m high in "
            f"{depth:g} m of water, whose crests would overtop the tank's walls "
            f"({freeboard:.3g} m above the still water): shorten stroke (at most "
            f"{2 * freeboard / ratio:.3g} m) or deepen the water (depth)."
        )


def _stroke(c: dict, period: float, t_end: float, dtype) -> StrokeParams:
    """The piston's position table X(t) = (S/2) r(t) sin(2 pi t / T) to one period
    past `t_end`, 40 samples a period; r ramps over `ramp_periods` periods (none
    at 0: the full stroke from the start, and no 0 / 0)."""
    times = np.linspace(0.0, t_end + period, int((t_end + period) / period * 40) + 1)
    ramp_time = float(c["ramp_periods"]) * period
    ramp = (
        np.clip(times / ramp_time, 0.0, 1.0) if ramp_time > 0 else np.ones_like(times)
    )
    stroke = 0.5 * float(c["stroke"]) * ramp * np.sin(2 * math.pi * times / period)
    return StrokeParams(
        times=np.asarray(times, dtype), stroke=np.asarray(stroke, dtype)
    )


def wave_tank(**overrides) -> Case:
    """Still water of `depth` in a tank of `tank_length`; a piston at x = 0 moves
    with X(t) = (S/2) r(t) sin(2 pi t / T), r ramping linearly from 0 to 1 over
    `ramp_periods` periods; the far end is a vertical wall or a 1:`beach_slope` beach.

    Probes: `eta` (strip-volume surface elevation at `gauge_x`, strip 5 l0 wide).
    """
    c = resolve("wave_tank", DEFAULTS, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("wave_tank is 2-D only for now (dim=2).")
    l0 = c["spacing"]
    length, depth = setting_length(c, "tank_length"), setting_length(c, "depth")
    check_gauge(overrides, c, length)
    period = float(c["wave_period"])
    k = _wave_number(period, depth, c["gravity"], l0)
    height = whole(1.6 * depth, l0)
    _check_stroke(float(c["stroke"]), piston_height_ratio(k, depth), depth, height)
    half_stroke = 0.5 * float(c["stroke"])
    layers = boundary_layers(c)
    travel = whole(half_stroke + l0, l0)

    fluid = geometry.block([0.0, 0.0], [length, depth], l0)
    # Bed from behind the piston's travel to the far end; far wall (tank() pieces).
    walls, wall_kind = geometry.tank(
        [-travel - layers * l0, 0.0], [length, height], l0, layers=layers
    )
    keep = walls[:, 0] > -travel - layers * l0  # drop the left wall: the piston
    walls, wall_kind = walls[keep], wall_kind[keep]
    if c["end"] == "beach":
        toe = length - depth * float(c["beach_slope"]) * 1.2
        s = float(c["beach_slope"])
        grid = geometry.block([toe, 0.0], [length, height], l0)
        surface = (grid[:, 0] - toe) / s
        below = grid[:, 1] < surface
        dist = (surface - grid[:, 1]) / math.sqrt(1 + 1 / s**2)
        beach = grid[below & (dist < layers * l0)]
        beach_layer = np.floor(dist[below & (dist < layers * l0)] / l0).astype(int)
        fluid = fluid[
            ~((fluid[:, 0] > toe) & (fluid[:, 1] < (fluid[:, 0] - toe) / s + 0.5 * l0))
        ]
        walls = np.concatenate([walls, beach])
        wall_kind = np.concatenate(
            [wall_kind, np.where(beach_layer == 0, Kind.WALL, Kind.DUMMY)]
        ).astype(np.int32)
    # Piston: a pressure layer at x = -l0/2 and dummies behind, full tank height.
    rows = int(round(height / l0))
    ys = (np.arange(rows) + 0.5) * l0
    piston = np.concatenate(
        [np.stack([np.full(rows, -(k + 0.5) * l0), ys], -1) for k in range(layers)]
    )
    piston_kind = np.where(np.arange(len(piston)) < rows, Kind.WALL, Kind.DUMMY)
    position = np.concatenate([fluid, piston, walls])
    kind = np.concatenate(
        [np.full(len(fluid), int(Kind.FLUID)), piston_kind, wall_kind]
    ).astype(np.int32)
    n_fluid = len(fluid)

    lower = np.array([-travel - (layers + 3) * l0, -(layers + 2) * l0])
    upper = np.array([length + (layers + 3) * l0, height + depth])
    scene = case_scene(c, position, (lower, upper), kind)
    motion = PrescribedMotion(
        particles=tuple(range(n_fluid, n_fluid + len(piston))),
        axis=(1.0, 0.0),
        law=Tabulated(),
    )
    scene = eqx.tree_at(lambda s: s.motion, scene, motion, is_leaf=lambda x: x is None)
    omega_scale = 2 * math.pi * half_stroke / period
    velocity_scale = max(math.sqrt(c["gravity"] * depth), omega_scale)
    params = case_params(c, 2, velocity_scale)
    t_end = float(c["t_end"])
    motion_params = _stroke(c, period, t_end, params.dt.dtype)
    params = eqx.tree_at(
        lambda p: p.motion, params, motion_params, is_leaf=lambda x: x is None
    )
    state = make_state(scene, position, kind)
    probes = (StripLevel("eta", float(c["gauge_x"]), 5 * l0, l0, depth),)
    config = {
        **c,
        "tank_length": length,
        "depth": depth,
        "wave_number": k,
        "linear_wave_height": piston_height_ratio(k, depth) * float(c["stroke"]),
    }
    return Case(
        name="wave_tank",
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=t_end,
        config=config,
    )
