"""Open-channel flume: inflow at unit discharge q, free overfall or tail weir."""

import math

import equinox as eqx
import numpy as np

from .. import geometry
from .._build import add_rigid_bodies, make_state
from .._params import Params
from .._scene import Scene
from .._types import Kind
from ..fluid import Inflow, InflowParams, Outflow
from ._bodies import block_probes, coulomb
from ._case import Case
from ._common import (
    boundary_layers,
    case_params,
    case_scene,
    resolve,
    setting_length,
)
from ._flume_bed import (
    bed_particles,
    bed_profile,
    check_lengths,
    fill,
    optional,
    stored_area,
)
from ._flume_grains import (
    MOVABLE_BED,
    add_bed_grains,
    bed_grains,
    block_sink,
    clear_of,
    movable_stretch,
    pit_depth,
)
from ._probes import BodiesMoved, FluidCount, WaterLevel

DEFAULTS = {
    "discharge": 0.04,  # unit discharge q [m^2/s] (seed 002 Ch. 4)
    "inflow_depth": 0.045,  # h_in [m] (seed 002 Ch. 4: 4.5 cm on the weir crest)
    "bed_length": 1.0,
    "weir_height": 0.0,  # tail weir at the downstream end; 0 = free overfall
    # The groundsill (seed 002 §3, §6): its crest, where the inflow enters (None:
    # the whole bed is one flat crest), a step down by step_height to an apron,
    # the reach at the apron's level (blocks and a scour hole lie in it), a
    # transition falling by bed_lowering (Delta H) to the lowered bed.
    "crest_length": None,
    "step_height": 0.0,
    "apron_length": 0.0,
    "reach_length": 0.0,
    "transition_length": 0.0,
    "bed_lowering": 0.0,
    # A fixed-bed scour hole just below the blocks (or the apron): seed 002's
    # Method A shape, from depth scour_exposure at its upstream end to
    # scour_depth at scour_centre (None: the middle) and back up at scour_length.
    "scour_length": 0.0,
    "scour_depth": 0.0,
    "scour_centre": None,
    "scour_exposure": 0.0,
    # Rows of bed-protection blocks (PMS rigid bodies, seed 002 §4, §6.4) from the
    # apron's end downstream, block_gap apart, their tops level with the apron
    # (they sit in a recess of the bed).
    "block_rows": 0,
    "block_length": 0.019,
    "block_height": 0.013,
    "block_gap": 0.0,
    "block_density": 2300.0,
    "mu_static": 0.6,
    "mu_kinetic": None,
    "friction_normal": "submerged_weight",
    "friction_torque": True,
    # The blocks are held still until release_time [s] while the flow spins up
    # round them (seed 002's spin-up with the blocks frozen); None: free at once.
    "release_time": None,
    # A movable bed of DEM grains (seed 002 Ch. 6-7; `_flume_grains`), feeling
    # no flow until release_time.
    **MOVABLE_BED,
    "initial_fill": True,  # start with the bed covered at h_in moving at q/h_in
    # ... and standing at least tail_depth over the bed's end (None: no more),
    # moving at q / depth: a start near the level a tail weir holds.
    "tail_depth": None,
    "pool": None,  # inactive slots for the inflow (default: enough for t_end)
    "spacing": 0.005,
    "dim": 2,
    "t_end": 2.0,
}

# The settings that are lengths along or across the bed, rounded to whole
# spacings (0 stays 0).
_PIECES = (
    "step_height",
    "apron_length",
    "reach_length",
    "transition_length",
    "bed_lowering",
    "scour_length",
    "scour_depth",
    "scour_exposure",
    "block_gap",
    "movable_length",
    "movable_depth",
)


def flume(**overrides) -> Case:
    """2-D flume of `bed_length` fed by an inflow of depth `inflow_depth` at speed
    `discharge / inflow_depth`; water leaves over the downstream end (deleted one
    spacing past it) or over a tail weir of `weir_height` (deleted once past its
    downstream face).

    The bed is flat by default (seed 002's Ch. 4 inflow on a flat bed). With
    `crest_length` it is a groundsill (seed 002 §3, §6): the inflow enters on
    its crest, which ends in a step `step_height` down to an apron of
    `apron_length`; below it a reach of `reach_length` at the apron's level, then
    a transition falling by `bed_lowering` (Delta H) over `transition_length` to
    the lowered bed, which runs on to `bed_length`. Seed 002's Ch. 4 step flow
    is `crest_length=0.1, step_height=0.1, bed_length=2.6` with a tail weir; its
    Case 2-2 groundsill `step_height=0.02, apron_length=0.1, reach_length=0.29,
    transition_length=0.5, bed_lowering=0.02` (the main body's 3 cm in the
    crest). A fixed-bed scour hole (`scour_length`, `scour_depth`,
    `scour_centre`, `scour_exposure`: seed 002's Method A shape, straight
    sides) may lie in the reach just below the apron or the blocks. Every
    length is rounded to whole spacings. Walls line the bed's surface,
    including its steps and slopes (a lattice staircase), with dummies behind.

    `tail_depth` starts the water standing that deep over the bed's end (with a
    tail weir: the level it will hold, near weir + (q / 1.83)^(2/3) for a
    sharp crest), to shorten the spin-up.

    `block_rows` rows of bed-protection blocks (`block_length` x `block_height`,
    `block_density`, `block_gap` apart, the first one gap below the apron) sit
    in a recess of the reach with their tops level with the apron: PMS rigid
    bodies with friction `mu_static`, `mu_kinetic` against the bed and each
    other, the normal force `friction_normal` (default seed 002's submerged
    weight). With `release_time` they are held still until then while the
    flow spins up round them.

    `movable_length` lays a movable bed (seed 002 Ch. 6-7) from
    `movable_start` (the apron's end by default): a pit cut `movable_depth`
    below the bed's highest surface over that stretch, filled with DEM grains
    of the spacing's diameter in seed 002's packed bed (`grain_density`,
    `friction`, `restitution`, `stiffness`, ...: `jaxmps.add_grains`), attached
    to the bed as walls to the water until the flow moves them; they feel no
    flow until `release_time`, settling under their own weight. Blocks in the
    stretch rest on them.

    Probes: `fluid_count`; `level_upstream`, `level_middle`,
    `level_downstream` (depth over the local bed at 0.25, 0.5 and 0.9 of the
    bed); with blocks, `block{k}_x`, `block{k}_y`, `block{k}_angle` for each
    row k counted from the apron, and `blocks_out`: how many have left their
    place (moved by more than one block length); with a movable bed,
    `scour_depth` and `scour_length` (`BedLowering`).
    """
    c = resolve("flume", DEFAULTS, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("flume is 2-D only for now (dim=2).")
    l0 = c["spacing"]
    h_in = setting_length(c, "inflow_depth")
    length = setting_length(c, "bed_length")
    weir = setting_length(c, "weir_height") if c["weir_height"] > 0 else 0.0
    c = _rounded(c, l0)
    check_lengths(c, length)
    u_in = float(c["discharge"]) / h_in
    layers = boundary_layers(c)
    rows = int(round(h_in / l0))
    profile = bed_profile(c, length, -(layers + 1) * l0)
    end = profile.knots[-1, 1]
    level, top = _heights(c, h_in, weir, end, length)
    stretch = movable_stretch(c, profile, length)
    inflow_pts, inflow_kind, upstream, upstream_kind, bed, bed_kind = _walls(
        c, profile, rows, max(top, level + 4 * l0), weir, length, stretch
    )
    blocks, body = _blocks(c, profile, l0, block_sink(c, profile, stretch))
    grains = bed_grains(profile, stretch, l0)
    tail = None if c["tail_depth"] is None else end + setting_length(c, "tail_depth")
    fluid, speed = _water(c, profile, length, h_in, tail, (blocks, grains))
    position = np.concatenate([fluid, blocks, grains, inflow_pts, upstream, bed])
    n_fluid, n_solid = len(fluid), len(blocks) + len(grains)
    kind = _kinds(n_fluid + n_solid, inflow_kind, upstream_kind, bed_kind)
    first_wall = n_fluid + n_solid
    held = [end + level] if weir else []
    held = max(held + ([] if tail is None else [tail]), default=None)
    area = stored_area(profile, length, h_in, held, l0)
    if stretch is not None:  # a movable bed may be scoured down to its floor
        area += (stretch[1] - stretch[0]) * pit_depth(profile, stretch)
    pool = _pool(c, u_in, area, rows, n_fluid)
    floor = profile.lowest if stretch is None else stretch[2]
    extent, inflow = (top, length, weir, floor), (first_wall, rows, len(inflow_pts))
    scene = _scene(c, position, kind, len(position) + pool, extent, inflow)
    params = _params(c, u_in, h_in)
    inflow_slots = slice(first_wall, first_wall + len(inflow_pts))
    velocity = _velocities(position, n_fluid, speed, inflow_slots, u_in)
    state = make_state(scene, position, kind, velocity=velocity)
    probes = _level_probes(profile, length, l0)
    case = _add_blocks(c, body, n_fluid, (scene, params, state, probes))
    scene, params, state, probes = add_bed_grains(
        c, stretch, n_fluid + len(blocks), len(grains), case
    )
    config = dict(c, inflow_depth=h_in, bed_length=length, weir_height=weir, pool=pool)
    config.update(apron_end=profile.apron_end, protection_end=profile.protection_end)
    config["movable_stretch"] = stretch
    return Case("flume", scene, params, state, probes, float(c["t_end"]), config)


def _velocities(position, n_fluid: int, speed, inflow: slice, u_in: float):
    """The initial velocities: the water's `speed` along x, the inflow's walls
    moving at `u_in`, the rest at rest."""
    velocity = np.zeros_like(position)
    velocity[:n_fluid, 0] = speed
    velocity[inflow, 0] = u_in
    return velocity


def _kinds(n_moving: int, *walls) -> np.ndarray:
    """Kinds in the flume's order: its water and blocks (fluid until the blocks
    are made rigid), then the wall groups."""
    return np.concatenate([np.full(n_moving, int(Kind.FLUID)), *walls]).astype(np.int32)


def _params(c: dict, u_in: float, h_in: float) -> Params:
    """The flume's Params: its step from the Courant rule of the inflow's speed
    and the wave speed over the crest and the drop, and the inflow's speed."""
    params = case_params(
        c, 2, u_in + math.sqrt(c["gravity"] * (h_in + c["step_height"]))
    )
    return _with_inflow(
        params, InflowParams(velocity=np.asarray(u_in, params.dt.dtype))
    )


def _scene(c: dict, position, kind, capacity: int, extent, inflow):
    """The flume's Scene: a domain from the inflow's dummies to beyond the
    downstream end and below the `lowest` bed (or the movable bed's floor), the
    inflow (`inflow`: the index of its first wall particle, its rows, its
    particle count) and the outflow."""
    top, length, weir, lowest = extent
    first_wall, rows, n_inflow = inflow
    l0, layers = c["spacing"], boundary_layers(c)
    lower = np.array([-(layers + 3) * l0, lowest - (layers + 2) * l0 - 0.2 * length])
    upper = np.array([length + (layers + 3) * l0, top])
    # Choice: with a movable bed, grains carried off are hidden from the water
    # and share its space: a place may hold the fluid's lattice and the packed
    # bed's 1.25 n0 at once (measured: the default margins overflowed as soon
    # as light grains were lifted into the flow), hence 1.5 times the margins.
    crowding = 1.5 if c["movable_length"] else 1.0
    scene = case_scene(
        c, position, (lower, upper), kind, capacity=capacity, crowding=crowding
    )
    # Choice: behind a weir the outflow plane is the weir's downstream face: water
    # that spills over the crest and runs down that face would otherwise fall
    # between the face and a plane further out and leave the domain through its
    # bottom.
    outflow_at = length + layers * l0 if weir > 0 else length + l0
    return _with_boundaries(
        scene,
        Inflow(
            pressure_layer=tuple(range(first_wall, first_wall + rows)),
            boundary=tuple(range(first_wall, first_wall + n_inflow)),
            origin=-0.5 * l0,
        ),
        Outflow(position=outflow_at),
    )


def _level_probes(profile, length: float, l0: float) -> tuple:
    """The fluid count and the depths over the local bed at 0.25, 0.5 and 0.9 of
    the bed."""
    return (
        FluidCount("fluid_count"),
        *(
            WaterLevel(name, at * length, float(profile.height(at * length)), l0)
            for name, at in (
                ("level_upstream", 0.25),
                ("level_middle", 0.5),
                ("level_downstream", 0.9),
            )
        ),
    )


def _walls(c: dict, profile, rows, top: float, weir: float, length: float, pit):
    """The inflow's boundary columns, the head-box wall above them up to `top`,
    and the bed with the tail weir and the movable bed's `pit`, each with its
    kinds."""
    l0 = c["spacing"]
    layers = boundary_layers(c)
    # Inflow boundary: a pressure layer at x = -l0/2 and dummy layers behind it.
    inflow, inflow_kind = _column(0, rows, layers, l0)
    # A fixed wall above the inflow column, so that a level raised by a tail weir
    # (or a jump) cannot spill back over the inflow boundary.
    # Choice: the wall rises to the top of the domain (a head-box wall), so that
    # splash thrown back upstream (off a weir or a jump) cannot leave the domain
    # over the inflow end; it falls back into the channel.
    upstream, upstream_kind = _column(rows, int(round(top / l0)) - rows, layers, l0)
    # The bed runs on under the weir: a weir standing on the bed's end would leave
    # a gap under its bottom row through which the bottom fluid row leaks out.
    bed_end = length + (layers * l0 if weir > 0 else 0.0)
    bed, bed_kind = bed_particles(profile, bed_end, weir, layers, l0, pit)
    return inflow, inflow_kind, upstream, upstream_kind, bed, bed_kind


def _rounded(c: dict, l0: float) -> dict:
    """The bed's lengths as whole spacings (block sizes at least one)."""
    out = {key: optional(c[key], l0) for key in _PIECES}
    if c["crest_length"] is not None:
        out["crest_length"] = setting_length(c, "crest_length")
    for key in ("scour_centre", "movable_start"):
        if c[key] is not None:
            out[key] = setting_length(c, key)
    if c["block_rows"]:
        out["block_length"] = setting_length(c, "block_length")
        out["block_height"] = setting_length(c, "block_height")
    return {**c, **out}


def _water(c: dict, profile, length: float, h_in: float, tail, solids):
    """The initial water (none without `initial_fill`) clear of the `solids`
    (blocks, grains) and its speed: q / depth, but still between the blocks
    (moving, it would be squeezed into their faces in the first step and throw
    them out)."""
    l0 = c["spacing"]
    blocks, grains = solids
    fluid, depth = fill(profile, length, h_in, l0, tail)
    free = _outside(fluid, blocks, l0) & bool(c["initial_fill"])
    free &= clear_of(fluid, grains, 0.9 * l0)
    fluid, depth = fluid[free], depth[free]
    between = (fluid[:, 0] > profile.apron_end) & (fluid[:, 0] < profile.protection_end)
    between &= fluid[:, 1] < -c["step_height"]
    return fluid, np.where(between, 0.0, c["discharge"] / depth)


def _outside(points: np.ndarray, solids: np.ndarray, l0: float) -> np.ndarray:
    """Which lattice `points` are not also points of `solids` (same lattice)."""
    if not len(solids):
        return np.ones(len(points), bool)
    taken = {tuple(p) for p in np.rint(solids / l0 - 0.5).astype(int)}
    cells = np.rint(points / l0 - 0.5).astype(int)
    return np.array([tuple(p) not in taken for p in cells], bool)


def _blocks(c: dict, profile, l0: float, sink: float = 0.0):
    """The blocks' lattice points, lowered by `sink` (onto a packed bed, below
    0.134 l0), and each one's row (from the apron)."""
    count = int(c["block_rows"])
    if not count:
        return np.zeros((0, 2)), np.zeros(0, int)
    a, h, gap = c["block_length"], c["block_height"], c["block_gap"]
    top = -c["step_height"] - sink
    blocks = [
        geometry.block(
            [profile.apron_end + gap + k * (a + gap), top - h],
            [profile.apron_end + gap + k * (a + gap) + a, top],
            l0,
        )
        for k in range(count)
    ]
    body = np.concatenate([np.full(len(b), k) for k, b in enumerate(blocks)])
    return np.concatenate(blocks), body


def _add_blocks(c: dict, body, first: int, case: tuple) -> tuple:
    """The (scene, params, state, probes) of `case` with the blocks (from slot
    `first`) as PMS rigid bodies with friction, and their probes: each one's
    position and angle, and how many have left their place."""
    if not len(body):
        return case
    scene, params, state, probes = case
    owner = np.full(scene.capacity, -1)
    owner[first : first + len(body)] = body
    scene, params, state = add_rigid_bodies(
        scene,
        params,
        state,
        owner,
        density=c["block_density"],
        mu_static=c["mu_static"],
        mu_kinetic=c["mu_kinetic"],
        friction=coulomb(c),
        pressure="pairs",
        release_time=c["release_time"],
    )
    moved = BodiesMoved("blocks_out", state.rigid.centre, float(c["block_length"]))
    return scene, params, state, probes + block_probes(int(c["block_rows"])) + (moved,)


def _heights(c: dict, h_in: float, weir: float, end: float, length: float):
    """The highest water level expected over the bed's end (behind a weir ~ crest
    + 1.5 h_c, a broad-crested weir, with margin) and the domain's top (the
    crest is at 0, the bed's end at `end`)."""
    h_c = (float(c["discharge"]) ** 2 / c["gravity"]) ** (1 / 3)  # critical depth
    level = weir + 2 * max(h_c, h_in) if weir > 0 else h_in
    margin = c["domain_margin"]
    # Choice: room above the water for splash (a jet off a tail weir rises ~0.3 m).
    top = max(h_in, end + weir) + (max(0.3 * length, 0.4) if margin is None else margin)
    return level, top


def _column(first: int, count: int, layers: int, l0: float):
    """`layers` vertical columns of `count` points upstream of x = 0 (at x = -l0/2,
    -3 l0/2, ...), from row `first` up: the nearest column pressure walls, the
    others dummies."""
    ys = (first + np.arange(count) + 0.5) * l0
    points = np.concatenate(
        [np.stack([np.full(count, -(k + 0.5) * l0), ys], -1) for k in range(layers)]
    )
    kind = np.where(np.arange(len(points)) < count, Kind.WALL, Kind.DUMMY)
    return points, kind


def _weir(length: float, weir: float, layers: int, l0: float):
    """The tail weir's points at the bed's end and their kinds: every face that
    water can touch (upstream, crest, downstream) is lined with pressure walls, as
    dummies carry no pressure and an exposed dummy face lets fluid through."""
    w = geometry.block([length, 0.0], [length + layers * l0, weir], l0)
    exposed = np.minimum.reduce(
        [w[:, 0] - length, weir - w[:, 1], length + layers * l0 - w[:, 0]]
    )
    layer = np.rint(exposed / l0 - 0.5).astype(int)
    return w, np.where(layer == 0, Kind.WALL, Kind.DUMMY)


def _pool(c: dict, u_in: float, area: float, rows: int, n_fluid: int):
    """Inactive slots for the inflow: the `pool` setting, or enough for what enters
    over t_end on a dry bed, for 1.5 x the water `area` the bed holds at the
    inflow depth or up to the level a tail weir holds (and a movable bed's pit,
    which a scour may empty), or for the inflow depth (the flow deepens as it
    develops)."""
    if c["pool"] is not None:
        return int(c["pool"])
    l0 = c["spacing"]
    columns = math.ceil(u_in * float(c["t_end"]) / l0) + 2
    stored = math.ceil(1.5 * area / l0**2) + 4 * rows - n_fluid
    return max(rows * columns if not c["initial_fill"] else 0, stored, 4 * rows)


def _with_boundaries(scene: Scene, inflow: Inflow, outflow: Outflow) -> Scene:
    return eqx.tree_at(
        lambda s: (s.inflow, s.outflow),
        scene,
        (inflow, outflow),
        is_leaf=lambda x: x is None,
    )


def _with_inflow(params: Params, inflow: InflowParams) -> Params:
    return eqx.tree_at(lambda p: p.inflow, params, inflow, is_leaf=lambda x: x is None)
