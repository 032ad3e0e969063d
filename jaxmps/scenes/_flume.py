"""Open-channel flume: inflow at unit discharge q, free overfall or tail weir."""

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import geometry
from .._build import make_state
from .._params import Params
from .._scene import Scene
from .._state import State
from .._types import Kind
from ..fluid import Inflow, InflowParams, Outflow
from ._case import Case
from ._common import boundary_layers, case_params, case_scene, resolve, whole
from ._probes import AbstractProbe, WaterLevel

DEFAULTS = {
    "discharge": 0.04,  # unit discharge q [m^2/s] (seed 002 Ch. 4)
    "inflow_depth": 0.045,  # h_in [m] (seed 002 Ch. 4: 4.5 cm on the weir crest)
    "bed_length": 1.0,
    "weir_height": 0.0,  # tail weir at the downstream end; 0 = free overfall
    "initial_fill": True,  # start with the bed covered at h_in moving at q/h_in
    "pool": None,  # inactive slots for the inflow (default: enough for t_end)
    "spacing": 0.005,
    "dim": 2,
    "t_end": 2.0,
}


class FluidCount(AbstractProbe):
    """Number of active fluid particles (mass in units of one particle)."""

    name: str

    def __call__(self, scene: Scene, state: State) -> Float[Array, ""]:
        del scene
        fluid = state.active & (state.kind == int(Kind.FLUID))
        return jnp.sum(fluid).astype(state.position.dtype)


def flume(**overrides) -> Case:
    """2-D flume of `bed_length` fed by an inflow of depth `inflow_depth` at speed
    `discharge / inflow_depth`; water leaves over the downstream end (deleted one
    spacing past it) or over a tail weir of `weir_height` (deleted once past its
    downstream face).

    # Choice: seed 002's Ch. 4 inflow (q = 0.04 m^2/s, h_in = 4.5 cm, uniform
    # velocity) on a flat 1 m bed; its step, crest and slope are not modelled here.
    """
    c = resolve("flume", DEFAULTS, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("flume is 2-D only for now (dim=2).")
    l0 = c["spacing"]
    h_in = whole(c["inflow_depth"], l0)
    length = whole(c["bed_length"], l0)
    weir = whole(c["weir_height"], l0) if c["weir_height"] > 0 else 0.0
    u_in = float(c["discharge"]) / h_in
    layers = boundary_layers(c)
    rows = int(round(h_in / l0))

    # Inflow boundary: a pressure layer at x = -l0/2 and dummy layers behind it.
    inflow_pts, inflow_kind = _column(0, rows, layers, l0)
    # A fixed wall above the inflow column, so that a level raised by a tail weir
    # (or a jump) cannot spill back over the inflow boundary.
    level, top = _heights(c, h_in, weir, length)
    # Choice: the wall rises to the top of the domain (a head-box wall), so that
    # splash thrown back upstream (off a weir or a jump) cannot leave the domain
    # over the inflow end; it falls back into the channel.
    above = int(round(max(top, level + 4 * l0) / l0)) - rows
    upstream, upstream_kind = _column(rows, above, layers, l0)
    # Bed under the inflow (and the travel of its dummies) and the channel.
    bed_lower = [-(layers + 1) * l0, -layers * l0]
    # The bed runs on under the weir: a weir standing on the bed's end would leave
    # a gap under its bottom row through which the bottom fluid row leaks out.
    bed_end = length + (layers * l0 if weir > 0 else 0.0)
    bed = geometry.block(bed_lower, [bed_end, 0.0], l0)
    bed_layer = np.rint(-bed[:, 1] / l0 - 0.5).astype(int)
    bed_kind = np.where(bed_layer == 0, Kind.WALL, Kind.DUMMY)
    parts = [inflow_pts, upstream, bed]
    kinds = [inflow_kind, upstream_kind, bed_kind]
    if weir > 0:
        w, w_kind = _weir(length, weir, layers, l0)
        parts.append(w)
        kinds.append(w_kind)
    fluid = (
        geometry.block([0.0, 0.0], [length, h_in], l0)
        if c["initial_fill"]
        else np.zeros((0, 2))
    )
    position = np.concatenate([fluid] + parts)
    kind = np.concatenate(
        [np.full(len(fluid), int(Kind.FLUID))] + [k.astype(int) for k in kinds]
    ).astype(np.int32)
    n_fluid = len(fluid)

    pool = _pool(c, u_in, level, length, rows, n_fluid)
    capacity = len(position) + pool
    lower = np.array([-(layers + 3) * l0, -(layers + 2) * l0 - 0.2 * length])
    upper = np.array([length + (layers + 3) * l0, top])
    scene = case_scene(c, position, (lower, upper), kind, capacity=capacity)
    # Choice: behind a weir the outflow plane is the weir's downstream face: water
    # that spills over the crest and runs down that face would otherwise fall
    # between the face and a plane further out and leave the domain through its
    # bottom.
    outflow_at = length + layers * l0 if weir > 0 else length + l0
    scene = _with_boundaries(
        scene,
        Inflow(
            pressure_layer=tuple(range(n_fluid, n_fluid + rows)),
            boundary=tuple(range(n_fluid, n_fluid + len(inflow_pts))),
            origin=-0.5 * l0,
        ),
        Outflow(position=outflow_at),
    )
    params = case_params(c, 2, u_in + math.sqrt(c["gravity"] * h_in))
    params = _with_inflow(
        params, InflowParams(velocity=np.asarray(u_in, params.dt.dtype))
    )
    velocity = np.zeros_like(position)
    velocity[:n_fluid, 0] = u_in
    velocity[n_fluid : n_fluid + len(inflow_pts), 0] = u_in
    state = make_state(scene, position, kind, velocity=velocity)
    probes = (
        FluidCount("fluid_count"),
        WaterLevel("level_upstream", 0.25 * length, 0.0, l0),
        WaterLevel("level_middle", 0.5 * length, 0.0, l0),
        WaterLevel("level_downstream", 0.9 * length, 0.0, l0),
    )
    config = {
        **c,
        "inflow_depth": h_in,
        "bed_length": length,
        "weir_height": weir,
        "pool": pool,
    }
    return Case("flume", scene, params, state, probes, float(c["t_end"]), config)


def _heights(c: dict, h_in: float, weir: float, length: float):
    """The highest water level expected (upstream of a weir ~ crest + 1.5 h_c, a
    broad-crested weir, with margin) and the domain's top."""
    h_c = (float(c["discharge"]) ** 2 / c["gravity"]) ** (1 / 3)  # critical depth
    level = weir + 2 * max(h_c, h_in) if weir > 0 else h_in
    margin = c["domain_margin"]
    # Choice: room above the water for splash (a jet off a tail weir rises ~0.3 m).
    top = max(h_in, weir) + (max(0.3 * length, 0.4) if margin is None else margin)
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


def _pool(c: dict, u_in: float, level: float, length: float, rows: int, n_fluid: int):
    """Inactive slots for the inflow: the `pool` setting, or enough for what enters
    over t_end on a dry bed, for the bed filled up to 1.5 x the level a tail weir
    holds, or for the inflow depth (the flow deepens as it develops)."""
    if c["pool"] is not None:
        return int(c["pool"])
    l0 = c["spacing"]
    columns = math.ceil(u_in * float(c["t_end"]) / l0) + 2
    stored = math.ceil(1.5 * level * length / l0**2) + 4 * rows - n_fluid
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
