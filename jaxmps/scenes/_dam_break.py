"""Collapse of a water column (Martin & Moyce 1952; Koshizuka & Oka 1996)."""

from ._case import Case
from ._common import (
    check_gauge,
    nearest_wall,
    resolve,
    setting_length,
    tank_case,
    velocity_scale,
)
from ._probes import FrontPosition, PressureAt, StripLevel, WaterLevel

DEFAULTS = {
    "column_width": 0.146,
    "column_height": 0.292,
    "tank_length": 0.584,
    "tank_height": 0.438,
    "tank_width": 0.0365,  # 3-D only: extent across the tank
    "spacing": 0.00365,  # 40 particles across the column
    "dim": 2,
    "gauge_x": 0.438,  # water-level gauge position [m]
    "bed_depth": 0.0,  # still water over the floor beside the column [m] (0: dry)
    "t_end": 0.3,
}


def dam_break(**overrides) -> Case:
    """Column `column_width` x `column_height` at the left wall of a tank
    `tank_length` long; default Koshizuka & Oka's 0.146 m x 0.292 m in 0.584 m.
    `bed_depth` > 0 puts still water that deep over the rest of the floor (a dam
    break onto a wet bed; 0, the default, leaves it dry).

    Probes: `front` (surge-front position from the left wall, contiguous fluid within
    2 l0 of the floor), `column_height` (residual height at the left wall),
    `gauge` (water level at `gauge_x`), `gauge_depth` (smooth volume-based depth over
    4 l0 at `gauge_x`, for calibration), `pressure_right_wall` (pressure-wall particle
    on the right wall nearest height l0... 2 l0) and `pressure_left_wall`.
    """
    c = resolve("dam_break", DEFAULTS, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    a, h = setting_length(c, "column_width"), setting_length(c, "column_height")
    length, height = setting_length(c, "tank_length"), setting_length(c, "tank_height")
    if a >= length or h >= height:
        raise ValueError(
            "The column must fit in the tank: column_width < tank_length and "
            "column_height < tank_height."
        )
    check_gauge(overrides, c, length)
    across = [setting_length(c, "tank_width")] if dim == 3 else []
    bed = _bed(c, h)
    beds = [([a] + [0.0] * (dim - 1), [length] + across + [bed])] if bed else []
    scene, params, state, extra = tank_case(
        c,
        [0.0] * dim,
        [a] + across + [h],
        [0.0] * dim,
        [length] + across + [height],
        velocity_scale(h, c["gravity"]),
        beds,
    )
    n_fluid = int(state.active.sum()) - len(extra["walls"])
    mid = [0.5 * across[0]] if dim == 3 else []
    right = nearest_wall(
        extra["walls"], extra["wall_kind"], [length + 0.5 * l0] + mid + [1.5 * l0]
    )
    left = nearest_wall(
        extra["walls"], extra["wall_kind"], [-0.5 * l0] + mid + [1.5 * l0]
    )
    probes = (
        FrontPosition("front", 0.0, 0.0, 2 * l0, l0, int(round(length / l0)) // 2 + 1),
        WaterLevel("column_height", 0.5 * l0, 0.0, l0),
        WaterLevel("gauge", float(c["gauge_x"]), 0.0, l0),
        StripLevel("gauge_depth", float(c["gauge_x"]), 4 * l0, l0, 0.0, softness=1.0),
        PressureAt("pressure_right_wall", tuple(n_fluid + i for i in right)),
        PressureAt("pressure_left_wall", tuple(n_fluid + i for i in left)),
    )
    config = {
        **c,
        "column_width": a,
        "column_height": h,
        "tank_length": length,
        "tank_height": height,
        "bed_depth": bed,
    }
    return Case(
        name="dam_break",
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=float(c["t_end"]),
        config=config,
    )


def _bed(c: dict, column_height: float) -> float:
    """The `bed_depth` setting on the lattice (0: a dry floor; `RULES` refuses a
    negative one); ValueError naming it where it is not below the column."""
    depth = float(c["bed_depth"])
    if depth == 0:
        return 0.0
    bed = setting_length(c, "bed_depth")
    if bed >= column_height:
        raise ValueError(
            f"bed_depth={depth:g} m is not below the column ({column_height:g} m, "
            "column_height): nothing would break; lower bed_depth."
        )
    return bed
