"""Seed 000's application: a tsunami running up over a quay and carrying an
unmoored ship towards a building (seed 000 chapters 4-5), in 2-D (a cross-section)
and 3-D."""

import math

import equinox as eqx
import numpy as np

from .. import geometry
from .._build import add_elastic_bodies, add_rigid_bodies, make_state
from .._types import Kind
from ..bodies import ElasticBodies, shear_speed
from ..fluid import InflowParams, Outflow, inflow_boundary
from ._bodies import _body_scene
from ._case import Case
from ._common import boundary_layers, case_params, resolve, setting_length
from ._probes import (
    BodyValue,
    ColumnDepth,
    ElasticValue,
    FlowVelocity,
    FluidCount,
    WallForce,
    WallPressure,
)

# Lengths and times are the prototype's (full scale) and are Froude-scaled by
# `scale`; `spacing` is the model's particle size.
TSUNAMI_QUAY = {
    "scale": 1.0,  # model / prototype length; times scale by its square root
    "sea_depth": 12.0,
    "sea_length": 60.0,  # from the inflow boundary to the quay edge
    "quay_crest": 2.0,  # quay top above the still water
    "quay_length": 100.0,  # from the quay edge to the landward (outflow) end
    # The tsunami at the inflow boundary: a long wave of height `tsunami_height`
    # rising over `rise_time` (half a cosine), held for `hold_time`, falling over
    # `fall_time`.
    "tsunami_height": 8.0,
    "rise_time": 10.0,
    "hold_time": 20.0,
    "fall_time": 10.0,
    # The open sea beyond the inflow boundary: a wave reflected by the quay (or a
    # building) back to it leaves the domain instead of reflecting again off a
    # piston (`Inflow.absorbing`); False: a piston wave-maker, as seed 000's.
    "inflow_absorbing": True,
    # Or a dam break (seed 000 §3.1's flume): a reservoir `reservoir_length` long
    # behind a gate at the sea's seaward end, filled to `reservoir_depth` and
    # released at t = 0 (no inflow then).
    "reservoir_length": None,
    "reservoir_depth": None,
    # The ship (seed 000 Table 5.1-1): broadside to the flow, `ship_gap` seaward
    # of the quay edge, floating at `ship_draft`.
    "ship_beam": 17.0,  # along the flow
    "ship_length": 100.0,  # along the quay (3-D)
    "ship_draft": 4.0,
    "ship_height": 8.0,
    "ship_gap": 2.0,
    "ship": True,  # False: the tsunami alone
    "ship_body": "rigid",
    "mu_static": 0.5,
    "mu_kinetic": None,
    # Elastic ship only. Seed 000 §5.1.2 sets its particle ship "close to" a side
    # plate's EI = 7.1e9 Pa m^4 without saying how; a solid section 17 m deep has
    # that EI per metre at E = 12 EI / B^3 = 1.7e7 Pa (a choice).
    "youngs_modulus": 1.7e7,
    "poisson_ratio": 0.3,  # elastic ship only
    # The building (seed 000 Table 5.1-2) on the quay: none unless its depth is set.
    "building_depth": None,  # along the flow
    "building_length": 30.0,  # along the quay (3-D)
    "building_height": 38.0,
    "building_distance": 40.0,  # its front face from the quay edge
    "pressure_gauges": 3,  # on the building's front face, from its base up
    "pressure_spacing": 2.0,  # their spacing (the lowest half of it up)
    "width": None,  # 3-D channel width (default: ship length + 2 beams)
    "gauge_spacing": 3.0,  # quay gauges every so far from the edge (seed: 3 m)
    "gauges": 4,
    "offshore_gauge": 30.0,  # the sea gauge, seaward of the quay edge
    "pool": None,  # inactive slots for the inflow (default: what the wave brings)
    "spacing": 0.5,
    "dim": 2,
    "t_end": 40.0,
}

_LENGTHS = (
    "sea_depth",
    "sea_length",
    "quay_crest",
    "quay_length",
    "tsunami_height",
    "ship_beam",
    "ship_length",
    "ship_draft",
    "ship_height",
    "ship_gap",
    "building_depth",
    "building_length",
    "building_height",
    "building_distance",
    "width",
    "gauge_spacing",
    "offshore_gauge",
    "reservoir_length",
    "reservoir_depth",
    "pressure_spacing",
)
_TIMES = ("rise_time", "hold_time", "fall_time", "t_end")


def tsunami_quay(**overrides) -> Case:
    """A sea `sea_depth` deep and `sea_length` long, fed at its seaward end by an
    inflow boundary that brings in a long wave (`tsunami_height`, `rise_time`,
    `hold_time`, `fall_time`), in front of a quay whose top lies `quay_crest`
    above the still water and runs `quay_length` landward to an outflow. An
    unmoored ship (`ship_beam` x `ship_height`, `ship_length` along the quay in
    3-D) floats at `ship_draft` with its side `ship_gap` off the quay edge
    (`ship=False`: none, the tsunami alone);
    `ship_body` is "rigid" (friction `mu_static` / `mu_kinetic` with the quay) or
    "elastic" (`youngs_modulus`, `poisson_ratio`). With `building_depth` a
    building (`building_length` x `building_depth` x `building_height`) stands on
    the quay with its front face `building_distance` from the edge. In 3-D the
    channel is `width` wide between side walls, ship and building on its centre
    line.

    Lengths and times are the prototype's (seed 000: l0 = 1 m); `scale` scales
    the scene by Froude similarity (lengths x scale, times and velocities x
    sqrt(scale)), and `spacing` is the model's particle size. The built case is
    in model units.

    The wave at the boundary: depth h + eta(t) and velocity
    u = 2 (sqrt(g (h + eta)) - sqrt(g h)), the simple (Riemann) wave running
    onto still water of depth h. The boundary absorbs what the quay reflects
    back to it (`inflow_absorbing`, default: the sea beyond it is open), where a
    piston would pump the wave's discharge in against the reflection and raise
    the whole sea.

    Probes: `ship_x`, `ship_z` (centre), `ship_u`, `ship_w` (velocity),
    `ship_angle` (rigid only) with a ship, `fluid_count`, `sea_level` and `sea_u` at
    `offshore_gauge` (depth over the sea bed, mean flow velocity), `quay_depth_k`
    and `quay_u_k` at the k-th quay gauge (k = 1..`gauges`; inundation depth over
    the quay top); depths are the water in a column l0 wide (`ColumnDepth`, on
    the channel's centre line in 3-D), velocities the mean across the channel;
    and, with a building, `building_force` (the force on its front
    face, N or N/m in 2-D: the wall pressure and a rigid ship's contact push,
    `WallForce`; its time integral is the impulse).
    """
    c = resolve("tsunami_quay", TSUNAMI_QUAY, overrides)
    g = _geometry(c)
    dim = int(c["dim"])
    series = None if g["reservoir_length"] else _series(c, g)
    parts = _parts(c, g)
    position = np.concatenate([p for p, _ in parts.values()])
    kind = np.concatenate([k for _, k in parts.values()]).astype(np.int32)
    pool = 0 if series is None else _pool(c, g, series)
    scene = _body_scene(c, position, _domain(c, g), kind, capacity=len(position) + pool)
    params = case_params(c, dim, _speed(c, g, series))
    state = make_state(scene, position, kind)
    body = np.full(len(position), -1)
    n_sea, n_ship = len(parts["sea"][0]), len(parts["ship"][0])
    body[n_sea : n_sea + n_ship] = 0
    density = c["density"] * g["ship_draft"] / g["ship_height"]
    if c["ship"]:
        scene, params, state = _add_ship(c, scene, params, state, body, density)
    end = g["sea_length"] + g["quay_length"]
    scene = eqx.tree_at(
        lambda s: s.outflow, scene, Outflow(position=end), is_leaf=lambda x: x is None
    )
    if series is not None:
        _, _, inflow = _inflow(c, g, len(position) - len(parts["inflow"][0]))
        scene = eqx.tree_at(
            lambda s: s.inflow, scene, inflow, is_leaf=lambda x: x is None
        )
        params = eqx.tree_at(
            lambda p: p.inflow, params, series, is_leaf=lambda x: x is None
        )
    config = {**c, **g, "ship_density": density, "quay_edge": g["sea_length"]}
    dry = getattr(scene.solver, "surface_head", 0.0) * c["density"] * c["gravity"]
    probes = _probes(c, g, dry * c["spacing"])
    return Case("tsunami_quay", scene, params, state, probes, g["t_end"], config)


def _speed(c: dict, g: dict, series: InflowParams | None) -> float:
    """The velocity scale of the largest step: the wave's speed at the inflow plus
    its celerity, or the dam break's front speed 2 sqrt(g H)."""
    grav = c["gravity"]
    if series is None:
        return 2.0 * math.sqrt(grav * g["reservoir_depth"])
    u_max = float(np.max(series.velocity))
    return u_max + math.sqrt(grav * (g["sea_depth"] + g["tsunami_height"]))


def _add_ship(c: dict, scene, params, state, body, density: float):
    """The ship as a rigid body (with friction) or an elastic one."""
    if c["ship_body"] == "rigid":
        return add_rigid_bodies(
            scene,
            params,
            state,
            body,
            density=density,
            mu_static=c["mu_static"],
            mu_kinetic=c["mu_kinetic"],
        )
    # The fluid's pressure acts on a wetted elastic body once per step: the
    # largest step is bounded by its coupling limit (`ElasticBodies.limits`)
    # unless `dt` or `dt_max` is given (then checked against it).
    if c["dt"] == "adaptive" and c["dt_max"] is None:
        c_s = shear_speed(c["youngs_modulus"], c["poisson_ratio"], density)
        limit = 0.99 * ElasticBodies.coupling_courant * c["spacing"] / c_s
        dt = np.asarray(min(float(params.dt), limit), params.dt.dtype)
        params = eqx.tree_at(lambda p: p.dt, params, dt)
    scene, params, state = add_elastic_bodies(
        scene,
        params,
        state,
        body,
        youngs_modulus=c["youngs_modulus"],
        poisson_ratio=c["poisson_ratio"],
        density=density,
    )
    return scene, params, state


def _geometry(c: dict) -> dict:
    """The scene's lengths in model metres on the lattice of l0 (the wave height
    off it) and its times in model seconds, checked against each other."""
    l0, s = c["spacing"], c["scale"]
    g = {}
    for key in _LENGTHS:
        if c[key] is None:
            g[key] = None
            continue
        # `setting_length` refuses a length under half a spacing (built one
        # spacing long, a 0.5 m ship_gap at l0 = 2 m read 2 m), in model metres.
        try:
            g[key] = setting_length({key: float(c[key]) * s, "spacing": l0}, key)
        except ValueError as error:
            if s == 1.0:
                raise
            raise ValueError(f"{error} (model metres, at scale={s:g})") from None
    g["tsunami_height"] = float(c["tsunami_height"]) * s
    if (c["reservoir_length"] is None) != (c["reservoir_depth"] is None):
        raise ValueError(
            "A dam break needs both reservoir_length and reservoir_depth (or "
            "neither, for the inflow's wave)."
        )
    if g["reservoir_length"] is not None:
        if not g["reservoir_depth"] > g["sea_depth"]:
            raise ValueError("reservoir_depth must exceed sea_depth (a dam break).")
        # The walls' height follows the bore: the reservoir's head over the sea.
        g["tsunami_height"] = g["reservoir_depth"] - g["sea_depth"]
    for key in _TIMES:
        g[key] = float(c[key]) * math.sqrt(s)
    if g["width"] is None:
        g["width"] = g["ship_length"] + 2 * g["ship_beam"]
    _check_geometry(c, g)
    return g


def _check_geometry(c: dict, g: dict) -> None:
    """ValueError naming the setting when the parts overlap or leave the scene."""
    l0, dim = c["spacing"], int(c["dim"])
    if c["ship"]:
        _check_ship(c, g)
    if not 0 < g["offshore_gauge"] < g["sea_length"]:
        raise ValueError("offshore_gauge must lie in the sea (below sea_length).")
    if int(c["gauges"]) * g["gauge_spacing"] >= g["quay_length"]:
        raise ValueError("The quay gauges run past quay_length; fewer `gauges`.")
    if g["building_depth"] is None:
        return
    if g["building_distance"] + g["building_depth"] > g["quay_length"] - 2 * l0:
        raise ValueError(
            "The building stands past the quay's end; lower building_distance or "
            "lengthen quay_length."
        )
    if dim == 3 and g["building_length"] > g["width"]:
        raise ValueError("building_length does not fit in `width`.")
    if int(c["pressure_gauges"]) * g["pressure_spacing"] > g["building_height"]:
        raise ValueError(
            "The pressure gauges run above the building; fewer `pressure_gauges` or "
            "a smaller pressure_spacing."
        )


def _check_ship(c: dict, g: dict) -> None:
    """ValueError naming the setting when the ship cannot float where it is put."""
    l0 = c["spacing"]
    if not g["ship_draft"] < g["ship_height"]:
        raise ValueError("ship_draft must be below ship_height (the ship would sink).")
    if not g["ship_draft"] < g["sea_depth"]:
        raise ValueError(
            "ship_draft must be below sea_depth: the ship would rest on the sea bed."
        )
    if g["sea_length"] - g["ship_gap"] - g["ship_beam"] < 4 * l0:
        raise ValueError(
            "The ship reaches the inflow boundary; lengthen sea_length or shorten "
            "ship_gap / ship_beam."
        )
    if int(c["dim"]) == 3 and g["ship_length"] + 2 * l0 > g["width"]:
        raise ValueError("ship_length does not fit in `width`; widen the channel.")


def _series(c: dict, g: dict) -> InflowParams:
    """The wave at the inflow boundary: depth h + eta(t), velocity of the simple
    wave, sampled finely enough for linear interpolation (0.1 % of eta)."""
    rise, hold, fall = g["rise_time"], g["hold_time"], g["fall_time"]
    t = np.unique(
        np.concatenate(
            [
                np.linspace(0.0, rise, 41),
                np.linspace(rise, rise + hold, 2),
                np.linspace(rise + hold, rise + hold + fall, 41),
            ]
        )
    )
    eta = np.where(
        t < rise,
        0.5 * (1 - np.cos(np.pi * t / rise)),
        np.where(
            t <= rise + hold, 1.0, 0.5 * (1 + np.cos(np.pi * (t - rise - hold) / fall))
        ),
    )
    eta = g["tsunami_height"] * eta
    h, grav = g["sea_depth"], c["gravity"]
    velocity = 2 * (np.sqrt(grav * (h + eta)) - np.sqrt(grav * h))
    return InflowParams(velocity=velocity, times=t, depth=h + eta)


def _inflow_top(g: dict, l0: float) -> float:
    """The inflow boundary's height: two spacings above the wave's crest."""
    return (math.ceil((g["sea_depth"] + g["tsunami_height"]) / l0 - 1e-9) + 2) * l0


def _top(g: dict, l0: float) -> float:
    """The walls' top: room for the wave reflected off the quay (twice its height)."""
    h, eta = g["sea_depth"], g["tsunami_height"]
    return (math.ceil((h + max(2 * eta, g["quay_crest"] + eta)) / l0) + 2) * l0


def _across(g: dict, dim: int, length: float, l0: float) -> tuple[list, list]:
    """The lower and upper bounds across the channel of a part `length` long on its
    centre line, on the lattice (nothing in 2-D)."""
    if dim == 2:
        return [], []
    start = round(0.5 * (g["width"] - length) / l0) * l0
    return [start], [start + length]


def _parts(c: dict, g: dict) -> dict:
    """Each group of particles with its kinds, in the state's order: the sea (and
    the reservoir), the ship, the bed, quay and side walls, the building, and
    for the inflow's wave the wall above the inflow and the inflow boundary
    (last)."""
    l0, dim = c["spacing"], int(c["dim"])
    h, edge = g["sea_depth"], g["sea_length"]
    wide = [0.0] if dim == 3 else []
    width = [g["width"]] if dim == 3 else []
    lo, hi = _across(g, dim, g["ship_length"], l0)
    x0 = edge - g["ship_gap"] - g["ship_beam"]
    keel = h - g["ship_draft"]
    ship = geometry.block(
        [x0] + lo + [keel], [edge - g["ship_gap"]] + hi + [keel + g["ship_height"]], l0
    )
    if not c["ship"]:
        ship = ship[:0]
    sea = geometry.block([0.0] + wide + [0.0], [edge] + width + [h], l0)
    sea = geometry.remove_overlaps(sea, ship, 0.99 * l0)
    if g["reservoir_length"] is not None:
        reservoir = geometry.block(
            [-g["reservoir_length"]] + wide + [0.0],
            [0.0] + width + [g["reservoir_depth"]],
            l0,
        )
        sea = np.concatenate([reservoir, sea])
    parts = {
        "sea": (sea, np.full(len(sea), int(Kind.FLUID))),
        "ship": (ship, np.full(len(ship), int(Kind.FLUID))),
        "solid": _solid(c, g),
    }
    if g["building_depth"] is not None:
        parts["building"] = _building(c, g)
    if g["reservoir_length"] is not None:
        return parts
    top_in, layers = _inflow_top(g, l0), boundary_layers(c)
    head = geometry.block(
        [-layers * l0] + wide + [top_in], [0.0] + width + [_top(g, l0)], l0
    )
    parts["head"] = (head, np.where(head[:, 0] > -l0, Kind.WALL, Kind.DUMMY))
    points, kinds, _ = _inflow(c, g, 0)
    parts["inflow"] = (points, kinds)
    return parts


def _inflow(c: dict, g: dict, first: int):
    """The inflow boundary's particles, kinds and `Inflow` (first index `first`)."""
    l0, dim = c["spacing"], int(c["dim"])
    top_in = _inflow_top(g, l0)
    upper = [0.0] + ([g["width"]] if dim == 3 else []) + [top_in]
    return inflow_boundary(
        0.0,
        [0.0] * dim,
        upper,
        l0,
        layers=boundary_layers(c),
        first=first,
        absorbing=bool(c["inflow_absorbing"]),
    )


def _solid(c: dict, g: dict):
    """The bed, the quay, the reservoir's back wall and (3-D) the side walls,
    `layers` deep below the wetted surfaces: pressure walls in the first layer,
    dummies behind, the quay's interior left out."""
    l0, dim, layers = c["spacing"], int(c["dim"]), boundary_layers(c)
    edge, quay_top = g["sea_length"], g["sea_depth"] + g["quay_crest"]
    end = edge + g["quay_length"]
    if g["reservoir_length"] is None:
        back, start = -np.inf, -(layers + 2) * l0  # the bed runs under the inflow
    else:
        back = -g["reservoir_length"]
        start = back - layers * l0
    low, high = [start], [end]
    if dim == 3:
        low, high = low + [-layers * l0], high + [g["width"] + layers * l0]
    box = geometry.block(low + [-layers * l0], high + [_top(g, l0)], l0)
    x, z = box[:, 0], box[:, -1]
    # Distance to the wetted region: the sea (back < x < edge, z > 0) or above the
    # quay (x > back).
    behind = np.maximum(back - x, 0.0)
    to_sea = np.hypot(
        np.maximum(np.maximum(x - edge, 0.0), behind), np.maximum(-z, 0.0)
    )
    to_land = np.hypot(np.maximum(quay_top - z, 0.0), behind)
    distance = np.minimum(to_sea, to_land)
    if dim == 3:
        y = box[:, 1]
        beside = np.maximum(np.maximum(-y, y - g["width"]), 0.0)
        distance = np.hypot(distance, beside)
    layer = np.rint(distance / l0 - 0.5).astype(int)
    keep = (distance > 0) & (layer < layers)
    kinds = np.where(layer[keep] == 0, Kind.WALL, Kind.DUMMY)
    return box[keep], kinds


def _building(c: dict, g: dict):
    """The building on the quay: pressure walls on its faces, dummies behind."""
    l0, dim, layers = c["spacing"], int(c["dim"]), boundary_layers(c)
    front = g["sea_length"] + g["building_distance"]
    base = g["sea_depth"] + g["quay_crest"]
    lo, hi = _across(g, dim, g["building_length"], l0)
    box = geometry.block(
        [front] + lo + [base],
        [front + g["building_depth"]] + hi + [base + g["building_height"]],
        l0,
    )
    upper = np.array([front + g["building_depth"]] + hi + [base + g["building_height"]])
    lower = np.array([front] + lo + [-np.inf])  # the base is on the quay
    depth = np.min(np.minimum(box - lower, upper - box), axis=1)
    layer = np.rint(depth / l0 - 0.5).astype(int)
    keep = layer < layers
    return box[keep], np.where(layer[keep] == 0, Kind.WALL, Kind.DUMMY)


def _pool(c: dict, g: dict, series: InflowParams) -> int:
    """Inactive slots for the inflow: the `pool` setting, or 1.1 x the volume the
    wave brings in up to `t_end` (its discharge integrated) in particles. A run
    taken further than `t_end` may exhaust it (`Result.pool_exhausted` names
    the setting)."""
    if c["pool"] is not None:
        return int(c["pool"])
    l0, dim = c["spacing"], int(c["dim"])
    t_end = float(g["t_end"])
    t = np.asarray(series.times)
    t = np.unique(np.concatenate([t[t < t_end], [min(t_end, t[-1])]]))
    q = np.interp(t, series.times, np.asarray(series.velocity) * series.depth)
    volume = float(np.sum(0.5 * (q[1:] + q[:-1]) * np.diff(t)))
    across = g["width"] / l0 if dim == 3 else 1.0
    columns = math.ceil(_inflow_top(g, l0) / l0) * across
    return math.ceil(1.1 * volume * across / l0**2) + int(4 * columns)


def _domain(c: dict, g: dict):
    """The domain box: the scene with room for splash above the walls."""
    l0, dim = c["spacing"], int(c["dim"])
    margin = (boundary_layers(c) + 3) * l0
    end = g["sea_length"] + g["quay_length"]
    top = _top(g, l0)
    start = -margin - (g["reservoir_length"] or 0.0)
    lower = [start] + ([-margin] if dim == 3 else []) + [-margin]
    upper = [end + margin] + ([g["width"] + margin] if dim == 3 else [])
    highest = top
    if g["building_depth"] is not None:
        highest = max(top, g["sea_depth"] + g["quay_crest"] + g["building_height"])
    upper += [highest + 0.5 * top]
    return np.array(lower), np.array(upper)


def _probes(c: dict, g: dict, dry: float) -> tuple:
    """The ship, the sea and quay gauges and (with one) the building's force
    (`dry`: the pressure of a dry wall particle)."""
    l0, dim = c["spacing"], int(c["dim"])
    edge, quay_top = g["sea_length"], g["sea_depth"] + g["quay_crest"]
    up = dim - 1
    if not c["ship"]:
        ship = ()
    elif c["ship_body"] == "rigid":
        ship = (
            BodyValue("ship_x", 0, "centre", 0),
            BodyValue("ship_z", 0, "centre", up),
            BodyValue("ship_u", 0, "velocity", 0),
            BodyValue("ship_w", 0, "velocity", up),
            BodyValue("ship_angle", 0, "angle"),
        )
    else:
        ship = (
            ElasticValue("ship_x", 0, "centre", 0),
            ElasticValue("ship_z", 0, "centre", up),
            ElasticValue("ship_u", 0, "velocity", 0),
            ElasticValue("ship_w", 0, "velocity", up),
        )
    # Depth gauges count the water in a column (on the centre line in 3-D),
    # where the highest particle across a 3-D channel would read a splash.
    centre = (0.5 * g["width"],) if dim == 3 else ()
    sea_x = edge - g["offshore_gauge"] + 0.5 * l0
    gauges = [
        ColumnDepth("sea_level", (sea_x, *centre), 0.0, l0),
        FlowVelocity("sea_u", sea_x, l0),
    ]
    for k in range(1, int(c["gauges"]) + 1):
        x = edge + k * g["gauge_spacing"] - 0.5 * l0
        gauges.append(ColumnDepth(f"quay_depth_{k}", (x, *centre), quay_top, l0))
        gauges.append(FlowVelocity(f"quay_u_{k}", x, l0))
    probes = (*ship, FluidCount("fluid_count"), *gauges)
    if g["building_depth"] is None:
        return probes
    front = edge + g["building_distance"]
    lo, hi = _across(g, dim, g["building_length"], l0)
    force = WallForce(
        "building_force",
        tuple([front - 0.25 * l0] + lo + [quay_top]),
        tuple([front + l0] + hi + [quay_top + g["building_height"]]),
        l0,
        dry,
    )
    pressures = []
    for k in range(1, int(c["pressure_gauges"]) + 1):
        z = quay_top + (k - 0.5) * g["pressure_spacing"]
        mid = [0.5 * (lo[0] + hi[0])] if dim == 3 else []
        pressures.append(
            WallPressure(
                f"building_pressure_{k}",
                tuple(
                    [front - 0.25 * l0] + [m - 0.5 * l0 for m in mid] + [z - 0.5 * l0]
                ),
                tuple([front + l0] + [m + 0.5 * l0 for m in mid] + [z + 0.5 * l0]),
                dry,
            )
        )
    return (*probes, force, *pressures)
