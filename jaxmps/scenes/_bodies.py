"""Scenes with rigid bodies: floating box, friction tilt, block impact, and a dam break
carrying a box (seed 000 §4, §6, §8.4, §8.5)."""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import geometry
from .._build import NEIGHBOUR_SKIN, add_elastic_bodies, add_rigid_bodies, make_state
from .._result import result_code, result_message
from .._simulate import simulate
from .._step import step, with_neighbour_lists, without_neighbour_lists
from .._types import Kind
from ..bodies import (
    ContactPressure,
    ContactReaction,
    Coulomb,
    SubmergedWeight,
    pressure_speed,
)
from ._case import Case
from ._common import (
    boundary_layers,
    case_params,
    case_scene,
    discretisation,
    floating_sound_speed,
    resolve,
    setting_length,
    velocity_scale,
    whole,
    whole_above,
)
from ._probes import (
    BodyPressure,
    BodyValue,
    DisplacedDepth,
    ElasticValue,
    FrontPosition,
    PressureLevel,
    WallForce,
    WaterLevel,
)


def _rotate(points: np.ndarray, centre: np.ndarray, degrees: float) -> np.ndarray:
    """Rotate 2-D points (or 3-D points about the y axis, i.e. in the x-z plane)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    out = points - centre
    i, k = 0, points.shape[1] - 1
    x, z = out[:, i].copy(), out[:, k].copy()
    out[:, i], out[:, k] = c * x - s * z, s * x + c * z
    return out + centre


def _orientation(dim: int, degrees: float):
    """`add_rigid_bodies` orientation of one body heeled by `degrees` as `_rotate`."""
    if dim == 2:
        return [degrees]
    return [[0.0, -degrees, 0.0]]  # rotation about y taking x towards z is -angle


def _body_scene(config, position, domain, kind, capacity=None):
    """The scene of a case with bodies. A rotating or deforming body fills cells
    differently from the initial lattice: allow the densest lattice packing of a
    particle's stencil box (5 cells of (r_e + skin) / 2 a side), with margin."""
    stencil_box = 2.5 * (discretisation(config).r_e + NEIGHBOUR_SKIN)
    return case_scene(
        config,
        position,
        domain,
        kind,
        candidate_capacity=math.ceil(1.5 * (stencil_box + 1.0) ** position.shape[1]),
        capacity=capacity,
    )


def _body_case(config, fluid, box, walls, wall_kind, domain, speed, orientation):
    """Scene, params and state for fluid + one rigid box + walls."""
    dim = box.shape[1]
    position = np.concatenate([fluid, box, walls])
    kind = np.concatenate(
        [
            np.full(len(fluid), int(Kind.FLUID), np.int32),
            np.full(len(box), int(Kind.FLUID), np.int32),
            wall_kind,
        ]
    )
    body = np.concatenate(
        [np.full(len(fluid), -1), np.zeros(len(box), int), np.full(len(walls), -1)]
    )
    scene = _body_scene(config, position, domain, kind)
    params = case_params(config, dim, speed)
    state = make_state(scene, position, kind)
    friction = config.get("friction", Coulomb())
    return add_rigid_bodies(
        scene,
        params,
        state,
        body,
        density=config["density"] * config["density_ratio"],
        mu_static=config.get("mu_static", 0.0),
        mu_kinetic=config.get("mu_kinetic"),
        orientation=orientation,
        centre_of_mass=config.get("centre_of_mass"),
        gyration=config.get("gyration_radii"),
        friction=friction,
        pressure=config.get("pressure", "pairs"),
    )


def _domain(lower, upper, l0, top_margin):
    layers = 3  # boundary layers for r_e up to 3 l0
    lo = np.asarray(lower, float) - layers * l0 - 2 * l0
    hi = np.asarray(upper, float) + layers * l0 + 2 * l0
    hi[-1] = upper[-1] + top_margin
    return lo, hi


FLOATING_BOX = {
    "box_width": 0.2,
    "box_height": 0.1,
    "density_ratio": 0.5,
    "heel": 0.0,
    "bilge_radius": 0.0,
    "centre_of_gravity": None,
    "gyration": None,
    "initial_draft": None,
    "settle": None,  # derived from the solver (`_floating_settle`)
    "settle_damping": True,  # the explicit hold's velocities zeroed (`_held_spin_up`)
    "body_pressure": "fluid",
    "sound_speed": None,  # derived from the depth (`floating_sound_speed`)
    "tank_length": 0.8,
    "tank_width": 0.2,  # 3-D only
    "depth": 0.2,
    "spacing": 0.01,
    "dim": 2,
    "t_end": 2.0,
}


def _round_bilges(box, x0: float, width: float, bottom: float, radius: float):
    """The particles of a box (lower face at `bottom`, x from `x0` to x0 + width)
    inside arcs of `radius` at its two lower edges."""
    if radius <= 0:
        return box
    x, z = box[:, 0], box[:, -1]
    keep = np.ones(len(box), bool)
    for cx in (x0 + radius, x0 + width - radius):
        dx = x - cx
        dz = z - (bottom + radius)
        corner = (np.abs(dx) > 0) & (np.sign(dx) == np.sign(cx - x0 - 0.5 * width))
        outside = (dz < 0) & corner & (dx**2 + dz**2 > radius**2)
        keep &= ~outside
    return box[keep]


def _mass_properties(c: dict, box: np.ndarray, keel: float) -> dict:
    """The box's centre of mass from its particles' centroid and its radii of
    gyration (`add_rigid_bodies`) from `centre_of_gravity` (height above the keel)
    and `gyration` (about the heel axis; about the others the particles' own about
    the centre of mass), in the unheeled frame; {} for a uniform box."""
    dim = box.shape[1]
    kg, radius = c["centre_of_gravity"], c["gyration"]
    if kg is None and radius is None:
        return {}
    centroid = box.mean(axis=0)
    offset = np.zeros(dim)
    if kg is not None:
        top = box[:, -1].max() + 0.5 * c["spacing"]
        if not keel < keel + kg < top:
            raise ValueError(
                f"centre_of_gravity must lie inside the box, between its keel and "
                f"its top ({top - keel:.4g} m above it), got {kg}."
            )
        offset[-1] = keel + kg - centroid[-1]
    out = {"centre_of_mass": offset}
    if radius is not None:
        arm = box - centroid - offset
        if dim == 2:
            out["gyration_radii"] = [radius]
        else:
            own = [np.mean(np.sum(np.delete(arm, a, 1) ** 2, 1)) for a in range(3)]
            out["gyration_radii"] = [own[0] ** 0.5, radius, own[2] ** 0.5]
    return out


def _release_draft(c: dict, bw: float, bh: float, depth: float) -> float:
    """The draft the box is released at [m], on the lattice: `initial_draft`, or
    Archimedes' (the section's area under the waterline is the density ratio
    times its whole area; the corners cut by the bilges are in neither)."""
    l0, radius = c["spacing"], float(c["bilge_radius"])
    if not 2 * radius <= min(bw, bh) + 1e-12:
        raise ValueError(
            "bilge_radius must be at most half of box_width and box_height."
        )
    draft = c["initial_draft"]
    corners = (2.0 - 0.5 * math.pi) * radius**2
    ratio = c["density_ratio"]
    draft = ratio * bh + (1 - ratio) * corners / bw if draft is None else float(draft)
    if not 0 <= draft < depth:
        raise ValueError("initial_draft must lie in [0, depth).")
    # On the lattice: an off-lattice box leaves a void or an overlap under its face.
    return round(draft / l0) * l0


def _floating_probes(
    c: dict, length: float, across: list, x0: float, bw: float, keel: float
) -> tuple:
    """The floating box's probes (see `floating_box`); `keel` is the bottom face's
    height in the box's frame (below its particles' centroid)."""
    l0, dim = c["spacing"], int(c["dim"])
    rho_g = c["density"] * c["gravity"]
    # Far columns: whole columns of the initial lattice, a quarter of the way from
    # each end wall to the box, half as wide as that gap.
    far_start = max(2, round(0.25 * x0 / l0)) * l0
    far_width = max(2, round(0.5 * x0 / l0)) * l0
    return (
        BodyValue("box_x", 0, "centre", 0),
        BodyValue("box_y", 0, "centre", dim - 1),
        BodyValue("box_angle", 0, "angle"),
        BodyValue("box_force_y", 0, "force", dim - 1),
        BodyPressure(
            "pressure_keel",
            0,
            (0.0,) * (dim - 1) + (keel,),
            (0.0,) * (dim - 1) + (-1.0,),
            l0,
            1.75 * l0,  # 3 or 4 columns: no lattice offset on its rim
        ),
        WaterLevel("level_left", 3.5 * l0, 0.0, l0),
        WaterLevel("level_right", length - 3.5 * l0, 0.0, l0),
        PressureLevel("surface_left", 5.5 * l0, 5 * l0, 0.0, rho_g, 2 * l0),
        PressureLevel("surface_right", length - 5.5 * l0, 5 * l0, 0.0, rho_g, 2 * l0),
        DisplacedDepth(
            "displaced",
            0,
            bw,
            (far_start + 0.5 * far_width, length - far_start - 0.5 * far_width),
            far_width,
            l0**dim,
            across[0] if across else 1.0,
        ),
    )


def floating_box(**overrides) -> Case:
    """A box `box_width` x `box_height` of density `density_ratio` x the water's,
    released at rest at `initial_draft` below the still-water surface (default: the
    Archimedes draft `density_ratio` x `box_height`; 0 drops it from the surface),
    heeled by `heel` degrees, in the middle of a tank `tank_length` long filled to
    `depth`. Fluid particles closer than l0/2 to the box are removed.
    `bilge_radius` rounds the box's two lower edges (a ship section: the
    particles outside the arcs are left out, and the box's mass with them; the
    default draft then leaves out the area of the corners too).
    The box is uniform unless `centre_of_gravity` (the height of its centre of
    mass above the keel, KG [m]) or `gyration` (its radius of gyration about the
    centre of mass for heel, about the axis along the tank's width [m]) is given
    (`Params.rigid.centre_of_mass`, `Params.rigid.gyration`).
    `body_pressure` is how the pressure acts on the box (`RigidBodies.pressure`):
    "fluid" (default; at Archimedes' draft) or "pairs".
    `settle` [s]: the water settles that long around the box held still (run
    when the case is built); the returned state is the settled one at time 0, the
    box's release. None (derived): five acoustic periods of the water column,
    20 `depth` / c, under the explicit solver, whose equation of state starts the
    lattice unpressurised; none under the semi-implicit one (`_floating_settle`).
    `settle_damping` (explicit solver, default True): zero the water's velocities
    16 times per acoustic period during the hold, so that it is released at rest
    under its settled pressure; False: it is released ringing
    (validation/floating_draft.py compares the two).

    Probes: `box_x`, `box_y` (centre), `box_angle` [rad], `box_force_y` (fluid force,
    gravity excluded), `pressure_keel` (the water's pressure on the bottom face's
    middle, `BodyPressure`),
    `level_left`, `level_right` (water level 3 l0 from each wall),
    `surface_left`, `surface_right` (the level where the hydrostatic pressure of a
    strip 3-8 l0 from each wall extrapolates to zero, `PressureLevel`),
    `displaced` (the depth of water the box displaces, counted by mass,
    `DisplacedDepth`). Archimedes: `displaced` is the box's mass over rho
    `box_width` (`density_ratio` x `box_height` without bilges), and so is the
    draft seen by the pressure (the pressure's surface minus the box's bottom
    face).
    """
    c = resolve("floating_box", FLOATING_BOX, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    if not c["density_ratio"] > 0:
        raise ValueError("density_ratio must be positive.")
    if c["body_pressure"] not in ("fluid", "pairs"):
        raise ValueError(
            f"body_pressure must be 'fluid' or 'pairs', got {c['body_pressure']!r}."
        )
    bw, bh = setting_length(c, "box_width"), setting_length(c, "box_height")
    length, depth = setting_length(c, "tank_length"), setting_length(c, "depth")
    c = {**c, "sound_speed": floating_sound_speed(c, depth)}
    if bw >= length:
        raise ValueError("box_width must be below tank_length.")
    across = [setting_length(c, "tank_width")] if dim == 3 else []
    height = depth + 2 * bh + 4 * l0
    x0 = whole(0.5 * (length - bw), l0)
    draft = _release_draft(c, bw, bh, depth)
    fluid = geometry.block([0.0] * dim, [length] + across + [depth], l0)
    box, keel = _floating_hull(c, x0, bw, bh, across, depth, draft)
    mass_properties = _mass_properties(c, box, depth - draft)
    if c["heel"]:
        box = _rotate(box, box.mean(axis=0), float(c["heel"]))
        # Clear fluid within 0.9 l0 of the tilted faces (0.5 l0 leaves particles
        # squeezed against them).
        fluid = geometry.remove_overlaps(fluid, box, 1.8 * l0)
    else:
        fluid = geometry.remove_overlaps(fluid, box, 0.99 * l0)
    walls, wall_kind = geometry.tank(
        [0.0] * dim, [length] + across + [height], l0, layers=boundary_layers(c)
    )
    scene, params, state = _body_case(
        {
            **c,
            **mass_properties,
            "mu_static": 0.0,
            "friction": None,
            "pressure": c["body_pressure"],
        },
        fluid,
        box,
        walls,
        wall_kind,
        _domain([0.0] * dim, [length] + across + [height], l0, 0.5 * height),
        velocity_scale(bh, c["gravity"]),
        _orientation(dim, float(c["heel"])),
    )
    settle = _floating_settle(c, depth)
    state = _floating_release(c, scene, params, state, settle, depth)
    probes = _floating_probes(c, length, across, x0, bw, keel)
    config = {
        **c,
        "settle": settle,
        "box_width": bw,
        "box_height": bh,
        "tank_length": length,
        "depth": depth,
    }
    return Case("floating_box", scene, params, state, probes, float(c["t_end"]), config)


FRICTION_TILT = {
    "body": "rigid",
    "youngs_modulus": 1.0e6,
    "poisson_ratio": 0.3,
    "substeps": None,
    "contact": "auto",
    "angle": 20.0,
    "mu_static": 0.5,
    "mu_kinetic": None,
    "block_size": 1.0,
    "block_height": None,
    "density_ratio": 1.5,
    "floor_length": 4.0,
    "spacing": 0.1,
    "dim": 2,
    "settle": 0.4,
    "friction_torque": False,
    "friction_normal": "reaction",
    "water_depth": 0.0,
    "body_pressure": "auto",
    "t_end": 1.0,
}

_NORMALS = {
    "reaction": ContactReaction,
    "pressure": ContactPressure,
    "submerged_weight": SubmergedWeight,
}


def _stacked_blocks(c, l0: float, length: float) -> tuple[list, float, dict]:
    """`block_stack`'s blocks (particle positions of each), their top and their
    sizes rounded to the lattice (`block_size`, `block_height`, `base_width`): stacked
    on the lowest (`base_width` wide, the others centred on it) or in a row with
    `gap` between them, from 0.1 of the floor (at most 0.5 m) along it."""
    count = int(c["blocks"])
    a = setting_length(c, "block_size")
    tall = a if c["block_height"] is None else setting_length(c, "block_height")
    # A clearance: under half a spacing it opens to one (the least the lattice
    # holds apart), not refused like a body's size.
    gap = whole(c["gap"], l0) if c["gap"] > 0 else 0.0
    x0 = whole(min(0.5, 0.1 * length), l0)
    base = a if c["base_width"] is None else setting_length(c, "base_width")
    widths = [a] * count
    if c["layout"] == "stack":
        widths[0] = base
        shift = whole(max(base - a, 0.0) / 2, l0)
        corners = [(x0 + (shift if k else 0.0), k * tall) for k in range(count)]
        top, right = count * tall, x0 + max(base, a + shift)
    else:
        corners = [(x0 + k * (a + gap), 0.0) for k in range(count)]
        top, right = tall, x0 + count * a + (count - 1) * gap
    if length < right + 2 * l0:
        raise ValueError(
            f"floor_length={length} is too short for the blocks (they reach "
            f"{right:g} m): raise floor_length."
        )
    blocks = [
        geometry.block([x, y], [x + w, y + tall], l0)
        for (x, y), w in zip(corners, widths)
    ]
    return blocks, top, {"block_size": a, "block_height": tall, "base_width": base}


def _tilt_body_pressure(c, depth: float) -> str:
    """`friction_tilt`'s `body_pressure`, `auto` resolved: `fluid` in water unless
    the normal force is the walls' reaction (which needs the pair form)."""
    if c["body_pressure"] != "auto":
        return c["body_pressure"]
    wet = depth > 0 and c["friction_normal"] != "reaction"
    return "fluid" if wet else "pairs"


def coulomb(c) -> Coulomb:
    """The Coulomb law of the settings `friction_normal` and `friction_torque`
    (ValueError naming a normal force that does not exist)."""
    if c["friction_normal"] not in _NORMALS:
        raise ValueError(
            f"friction_normal={c['friction_normal']!r} is not a normal force; "
            f"valid: {', '.join(_NORMALS)}."
        )
    return Coulomb(
        normal=_NORMALS[c["friction_normal"]](), torque=bool(c["friction_torque"])
    )


def block_probes(count: int) -> tuple:
    """`block{k}_x`, `block{k}_y`, `block{k}_angle` for rigid bodies 0..count-1."""
    return tuple(
        probe
        for k in range(count)
        for probe in (
            BodyValue(f"block{k}_x", k, "centre", 0),
            BodyValue(f"block{k}_y", k, "centre", 1),
            BodyValue(f"block{k}_angle", k, "angle"),
        )
    )


def _tilted_gravity(dim: int, g: float, degrees: float) -> np.ndarray:
    a = math.radians(degrees)
    out = np.zeros(dim)
    out[0], out[-1] = g * math.sin(a), -g * math.cos(a)
    return out


def _tilted_water(c, solids, length, what, top):
    """Still water over a floor [0, length] under gravity tilted by `angle`: the
    lattice points below a level surface `water_depth` above the floor at the
    middle of `solids` (the bodies' particles, which the water keeps l0 from),
    and the tank height that holds it. `top`: the bodies' height."""
    l0, depth = c["spacing"], float(c["water_depth"])
    if depth < top:
        raise ValueError(f"water_depth={depth} must cover {what} (height {top:g} m).")
    slope = math.tan(math.radians(float(c["angle"])))
    centre = (solids[:, 0].min() + solids[:, 0].max()) / 2
    if depth - slope * centre < l0:
        raise ValueError(
            "the water's surface under the tilted gravity meets the floor "
            "inside the tank: raise water_depth or lower angle."
        )
    surface = math.ceil((depth + slope * (length - centre)) / l0 - 1e-9) * l0
    grid = geometry.block([0.0, 0.0], [length, surface], l0)
    near = np.min(np.linalg.norm(grid[:, None] - solids[None], axis=-1), axis=1)
    below = grid[:, 1] < depth + slope * (grid[:, 0] - centre)
    return grid[(near > 0.5 * l0) & below], whole_above(surface + 0.2 * top, l0)


def _floating_settle(c: dict, depth: float) -> float:
    """`floating_box`'s `settle` setting, or where it is None (derived), five
    acoustic periods 4 `depth` / c of the water column under the explicit solver
    and 0 under the semi-implicit one.

    # Choice: the explicit solver's water starts on the lattice at n0, so without
    # pressure; a box released with it falls until the compression builds up, lands
    # deep and stays there. Measured (validation/floating_draft.py, density ratio
    # 0.6, l0 = B/20, c = 19.8 m/s, 3 s window): released at once at Archimedes'
    # draft it displaced +0.46 l0 too much (std 0.20 l0); after 0.1 / 0.2 /
    # 0.3 / 0.5 s held, -0.12 / -0.14 / -0.16 / -0.10 l0 (std 0.05). Released 2 l0
    # above or below Archimedes' at once, +0.06 / +0.03 (its larger heave shakes it
    # loose). At B/10 the 3 s means scatter by +-0.15 l0 with the release whether
    # held or not. The semi-implicit pressure is hydrostatic from the first step.
    """
    if c["settle"] is not None:
        return float(c["settle"])
    if c["solver"] != "explicit":
        return 0.0
    return 5 * 4 * depth / c["sound_speed"]


def _floating_hull(c: dict, x0, bw, bh, across, depth, draft):
    """The box's particles (bilges rounded by `bilge_radius`) floating at `draft`
    with its left face at `x0`, and its keel's height below its centre less l0/2
    [m] (the keel gauge's offset)."""
    l0, dim = c["spacing"], int(c["dim"])
    box = geometry.block(
        [x0] + [0.0] * (dim - 2) + [depth], [x0 + bw] + across + [depth + bh], l0
    )
    box = _round_bilges(box, x0, bw, depth, float(c["bilge_radius"]))
    keel = float(box[:, -1].min() - box[:, -1].mean()) - 0.5 * l0
    box[:, -1] -= draft
    return box, keel


def _floating_release(c: dict, scene, params, state, settle: float, depth: float):
    """`floating_box`'s state at the release: after `settle` s with the box held
    (none where 0), the explicit water's velocities zeroed 16 times per period of
    its column, 4 `depth` / c, where `settle_damping` (`_held_spin_up`)."""
    if not settle > 0:
        return state
    damp_every = (
        0.25 * depth / c["sound_speed"]
        if c["settle_damping"] and c["solver"] == "explicit"
        else None
    )
    return _held_spin_up(scene, params, state, settle, damp_every)


def _held_spin_up(scene, params, state, duration, damp_every=None):
    """The state after `duration` s with the rigid bodies held still, its clock set
    back to 0 (the bodies are released then). With `damp_every` [s], the hold runs
    in equal pieces of at most that length and the fluid's velocities are zeroed
    after each (an overdamped relaxation), so that the water is released at rest
    under its settled pressure.
    """
    # Choice: held undamped, the explicit water still rang after five periods of
    # its column (force on the box at the release 0.83-1.21 x its weight) and the
    # box's draft was a draw set by that kick: in a layer one box height deep the
    # 1.21 x kick pumped water under the box, where the jammed particle packing
    # kept it 0.7 rho g l0 over-pressured, and the box floated 0.64 l0 high for
    # good. Zeroed every 1/16 period: 0.94-0.99 x; draft matrix 1 row of 25
    # outside 0.3 l0 (3 of 22 undamped). Zeroing only at kinetic-energy peaks
    # fails: the water's particle noise regrows within one period.
    held = eqx.tree_at(
        lambda p: p.rigid.release_time,
        params,
        jnp.full_like(params.rigid.density, jnp.inf),
        is_leaf=lambda x: x is None,
    )
    if damp_every is None:
        return _spun_up(scene, held, state, duration)
    pieces = max(1, math.ceil(duration / damp_every - 1e-9))
    fluid = jnp.asarray(state.kind == int(Kind.FLUID))[:, None]
    for _ in range(pieces):
        state = _spun_up(scene, held, state, duration / pieces)
        state = eqx.tree_at(
            lambda s: s.velocity, state, jnp.where(fluid, 0.0, state.velocity)
        )
    return state


def _spun_up(scene, params, state, duration, gravity=None):
    """The state after `duration` s of settling, its clock set back to 0. With
    `gravity`, under that gravity and with the bodies held by friction (seed 002
    spins up with its blocks frozen); otherwise under `params` as they are."""
    if gravity is not None:
        held = jnp.full_like(params.rigid.mu_static, 1e3)
        params = eqx.tree_at(
            lambda p: (p.gravity, p.rigid.mu_static, p.rigid.mu_kinetic),
            params,
            (gravity, held, held),
        )
    out = simulate(scene, params, state, times=[duration], throw=False)
    if int(np.asarray(result_code(out.result))) != 0:
        raise ValueError(
            f"The spin-up before the bodies' release (settle={duration:g} s) stopped "
            f"at t = {float(out.state.time):.3g} s: {result_message(out.result)} "
            "Check the bodies' settings (density_ratio, mu_static, gap, ...), or "
            "release at once with settle=0."
        )
    state = out.state
    return eqx.tree_at(
        lambda s: (s.time, s.step),
        state,
        (jnp.zeros_like(state.time), jnp.zeros_like(state.step)),
    )


def _tilt_dt_max(c, l0: float) -> float:
    """`friction_tilt`'s largest step: 0.002 s x (l0 / 0.1 m), and for an
    elastic block met through the pressure at most DRY_CONTACT_COURANT l0 /
    c_p."""
    dt_max = 0.002 * l0 / 0.1
    if c["body"] == "elastic" and c["contact"] == "pressure":
        density = c["density"] * c["density_ratio"]
        c_p = float(pressure_speed(c["youngs_modulus"], c["poisson_ratio"], density))
        dt_max = min(dt_max, DRY_CONTACT_COURANT * l0 / c_p)
    return dt_max


def friction_tilt(**overrides) -> Case:
    """Seed 000 §8.5: a rigid block (`block_size` cube of `density_ratio` x `density`,
    or `block_size` wide and `block_height` tall) on a flat floor, the slope
    emulated by tilting gravity by `angle` degrees (g_x = g sin(angle) down the
    floor, g_y = -g cos(angle)). It first settles for
    `settle` s under untilted gravity (run when the case is built) so that the
    contact pressure has built up; the returned state is the settled one at time 0.
    Theory: it stays for tan(angle) <= mu_static and otherwise slides with
    acceleration g (sin(angle) - mu_kinetic cos(angle)); with `friction_torque`, a
    block that does not slide tips over its lower edge where tan(angle) exceeds
    (width - l0) / (height - l0) (its particles' centres span width - l0, and its
    centre of mass lies (height - l0) / 2 above the bottom row).

    The time step defaults to 0.002 s x (spacing / 0.1 m): at 0.005 s (l0 = 0.1 m) the
    contact reaction was measured to chatter by +-17 % from step to step.

    `friction_normal` picks the normal force of the Coulomb law: `reaction` (the
    walls' reaction, default), `pressure` (seed 000: the touching particles'
    pressure) or `submerged_weight` (seed 002: (M - rho V) g cos(angle)).

    With `water_depth` > 0 the block stands in still water (2-D): the tank is
    filled to a surface level under the tilted gravity, `water_depth` above the
    floor at the block's centre, and the settling runs under the tilted gravity
    with the block held by friction (seed 002 spins up with its blocks frozen).
    Theory (seed 002 T10): with the submerged weight W = (M - rho V) g as the
    normal force's scale, the block stays for tan(angle) < mu_static and slides
    with acceleration (W / M g) g (sin(angle) - mu_kinetic cos(angle)), less the
    water's added mass and drag, which the formula leaves out (at the release the
    added mass of a block on the floor is of the order of its own; measured
    against linear potential flow of the same tank in validation/slide_in_water.py:
    0.96-1.09 x its travel). The water acts on
    the block as on the water it replaces (`body_pressure="fluid"`, what `auto`
    takes in water unless `friction_normal="reaction"`, which needs the pair
    form; `pairs` otherwise): with
    the pair form the tank pushed a block up the slope with 1.5 times its
    buoyancy's share, and it slid at a fifth of the theory.

    With `body="elastic"` the block is an elastic body (`youngs_modulus`,
    `poisson_ratio`, `substeps` as in `block_impact`) whose particles touching
    the floor take the friction (`jaxmps.bodies.ElasticBodies.friction_impulse`);
    dry only, and `friction_torque` is the rigid block's setting.

    Probes: `block_x`, `block_y`, `block_velocity_x` (the body's mean position and
    velocity), and for the rigid block `block_angle`, `friction_x`,
    `normal_force` (contact force along the floor normal).
    """
    c = resolve("friction_tilt", FRICTION_TILT, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    a = setting_length(c, "block_size")
    tall = a if c["block_height"] is None else setting_length(c, "block_height")
    length = setting_length(c, "floor_length")
    if length < a + 2 * l0:
        raise ValueError("floor_length must exceed block_size by at least 2 spacings.")
    if c["dt"] == "adaptive" and c["dt_max"] is None:
        c = {**c, "dt_max": _tilt_dt_max(c, l0)}
    x0 = whole(min(0.5, 0.1 * length), l0)
    across = [a + 4 * l0] if dim == 3 else []
    lower_box = [x0] + ([2 * l0] if dim == 3 else []) + [0.0]
    box = geometry.block(
        lower_box, [x0 + a] + ([2 * l0 + a] if dim == 3 else []) + [tall], l0
    )
    height = whole_above(1.2 * tall, l0)
    friction = coulomb(c)
    fluid = np.zeros((0, dim))
    depth = float(c["water_depth"])
    if depth > 0:
        if dim != 2:
            raise ValueError("water_depth is for the 2-D friction_tilt (dim=2).")
        fluid, height = _tilted_water(c, box, length, "the block", tall)
    walls, wall_kind = geometry.tank(
        [0.0] * dim, [length] + across + [height], l0, layers=boundary_layers(c)
    )
    tilted = _tilted_gravity(dim, c["gravity"], float(c["angle"]))
    domain = _domain([0.0] * dim, [length] + across + [height], l0, max(a, tall))
    config = {**c, "block_size": a, "block_height": tall, "floor_length": length}
    if c["body"] == "elastic":
        if depth > 0:
            raise ValueError(
                "water_depth is for the rigid block (body='rigid'); the elastic "
                "block of friction_tilt stands dry."
            )
        return _elastic_tilt(config, friction, box, walls, wall_kind, domain, tilted)
    c = {**c, "body_pressure": _tilt_body_pressure(c, depth)}
    config = {**config, "body_pressure": c["body_pressure"]}
    particles = (fluid, box, walls, wall_kind)
    return _rigid_tilt(c, config, friction, particles, domain, tilted)


def _rigid_tilt(c, config, friction, particles, domain, tilted) -> Case:
    """`friction_tilt` with a rigid block: settled (in water: held by friction
    under the tilted gravity), then the gravity tilted. `particles`: the fluid,
    the block, the walls and their kinds."""
    fluid, box, walls, wall_kind = particles
    dim, depth = box.shape[1], float(c["water_depth"])
    scene, params, state = _body_case(
        {**c, "friction": friction, "pressure": c["body_pressure"]},
        fluid,
        box,
        walls,
        wall_kind,
        domain,
        velocity_scale(config["block_size"], c["gravity"]),
        None,
    )
    tilted = jnp.asarray(tilted, params.gravity.dtype)
    if c["settle"] > 0:
        if depth > 0:  # held by friction under the tilted gravity
            state = _spun_up(scene, params, state, c["settle"], tilted)
        else:
            state = _spun_up(scene, params, state, c["settle"])
    params = eqx.tree_at(lambda p: p.gravity, params, tilted)
    probes = (
        BodyValue("block_x", 0, "centre", 0),
        BodyValue("block_y", 0, "centre", dim - 1),
        BodyValue("block_angle", 0, "angle"),
        BodyValue("block_velocity_x", 0, "velocity", 0),
        BodyValue("friction_x", 0, "friction", 0),
        BodyValue("normal_force", 0, "contact_force", dim - 1),
    )
    return Case(
        "friction_tilt", scene, params, state, probes, float(c["t_end"]), config
    )


# The largest step of an elastic body resting on walls, in l0 / c_p (c_p the
# P-wave speed). Measured (validation/block_impact.py's elastic block, E = 1e6 Pa,
# nu = 0.48, falling onto a floor, total kinetic energy after the contact against
# before): 0.59-0.78 at dt c_p / l0 = 0.09, 1.0-1.9 at 0.47 and 2.5-3.3 at 0.94
# (the contact through the pressure creates energy), and a 1 m block settled at
# 1.9 bounced on the floor with reactions from 0.01 to 6.5 M g.
DRY_CONTACT_COURANT = 0.2


@eqx.filter_jit
def _relax(scene, params, state, steps: int):
    es = state.elastic

    def energy(s):
        return jnp.sum(s.velocity[es.index] ** 2)

    def one(carry, _):
        s, before = carry
        s, _ = step(scene, params, s)
        now = energy(s)
        peak = now < before
        keep = jnp.where(peak, 0.0, 1.0)
        elastic = dataclasses.replace(
            s.elastic,
            velocity=keep * s.elastic.velocity,
            angular_velocity=keep * s.elastic.angular_velocity,
        )
        s = dataclasses.replace(
            s, velocity=s.velocity.at[es.index].multiply(keep), elastic=elastic
        )
        return (s, jnp.where(peak, 0.0, now)), None

    return jax.lax.scan(one, (state, energy(state)), None, length=steps)[0][0]


def _relaxed(scene, params, state, duration):
    """The elastic bodies' state after `duration` s of kinetic damping (dynamic
    relaxation): steps under `params`, every elastic velocity and spin zeroed at
    each step where the bodies' kinetic energy has fallen since the step before
    (a peak just passed). The bodies end near their static equilibrium, at rest;
    the clock is set back to 0.

    # Choice: the seed's elastic model has no damping, so a block settled by
    # plain steps keeps the vertical oscillation of its sudden loading (measured
    # with the pressure contact: the floor's reaction on a 1 m block, E = 1e6
    # Pa, dt = 2e-4 s, swinging between 0.12 and 1.7 M g in the 0.1 s after a
    # 0.4 s settle), and friction
    # in proportion to that reaction is not the friction of a block at rest."""
    steps = max(1, round(duration / float(params.dt)))
    state = _relax(scene, params, with_neighbour_lists(scene, state), steps)
    state = without_neighbour_lists(state)
    return eqx.tree_at(
        lambda s: (s.time, s.step),
        state,
        (jnp.zeros_like(state.time), jnp.zeros_like(state.step)),
    )


def _elastic_tilt(c, friction, box, walls, wall_kind, domain, tilted) -> Case:
    """`friction_tilt` with an elastic block: relaxed to rest (`_relaxed`) under
    the tilted gravity's normal component, then the gravity tilted."""
    dim = box.shape[1]
    scene, params, state = _elastic_block(
        c,
        box,
        walls,
        wall_kind,
        domain,
        np.zeros(dim),
        friction=friction,
        mu_static=c["mu_static"],
        mu_kinetic=c["mu_kinetic"],
        speed=velocity_scale(c["block_size"], c["gravity"]),
    )
    tilted = jnp.asarray(tilted, params.gravity.dtype)
    if c["settle"] > 0:
        normal = params.gravity.at[0].set(0.0).at[-1].set(tilted[-1])
        state = _relaxed(
            scene, eqx.tree_at(lambda p: p.gravity, params, normal), state, c["settle"]
        )
    params = eqx.tree_at(lambda p: p.gravity, params, tilted)
    probes = (
        ElasticValue("block_x", 0, "centre", 0),
        ElasticValue("block_y", 0, "centre", dim - 1),
        ElasticValue("block_velocity_x", 0, "velocity", 0),
    )
    return Case("friction_tilt", scene, params, state, probes, float(c["t_end"]), c)


BLOCK_STACK = {
    "layout": "stack",
    "blocks": 2,
    "block_size": 0.5,
    "block_height": None,
    "base_width": None,
    "gap": 0.0,
    "angle": 0.0,
    "mu_static": 0.6,
    "mu_kinetic": None,
    "density_ratio": 2.0,
    "floor_length": 3.0,
    "water_depth": 0.0,
    "friction_torque": True,
    "friction_normal": "reaction",
    "friction_sweeps": 64,
    "spacing": 0.05,
    "dim": 2,
    "settle": 0.3,
    "t_end": 1.0,
}


def block_stack(**overrides) -> Case:
    """Seed 002's blocks: `blocks` rigid blocks (`block_size` wide, `block_height`
    tall, `density_ratio` x `density`) stacked on each other (`layout="stack"`,
    the lowest `base_width` wide, the others centred on it) or
    side by side along the slope with `gap` between them (`layout="row"`), on a
    flat floor whose slope is emulated by tilting gravity by `angle` degrees, as
    in `friction_tilt`; in still water with `water_depth` > 0 (2-D).

    Each block has the friction coefficients `mu_static`, `mu_kinetic` against
    walls (`Params.rigid.mu_static` per block) and the smaller of two blocks'
    values between them. The blocks first settle for `settle` s under the tilted
    gravity held by friction (seed 002 spins up with its blocks frozen).
    Theory: a stacked block slides on the one below where tan(angle) exceeds
    their coefficient, with acceleration g (sin - mu_k cos) (dry), and no block
    tips before tan(angle) = (width - l0) / (height - l0) of the stack above its
    edge. `friction_normal` picks the normal force against walls as in
    `friction_tilt`; in water the walls' `reaction` carries the water standing on
    a block (no water gets under a block that rests on the floor's lattice), so
    seed 002's `submerged_weight` is the one its still-water tests assume.
    `friction_sweeps` resolves the friction between the blocks (a stack of
    three holds to 0.005 mm/s with the default 64, creeps at 0.2 mm/s with 32
    and 2.4 mm/s with 16; see `jaxmps.bodies.RigidBodies`).
    Probes per block k: `block{k}_x`, `block{k}_y`, `block{k}_angle`.
    """
    c = resolve("block_stack", BLOCK_STACK, overrides)
    sweeps = c["friction_sweeps"]
    if not (float(sweeps) == int(sweeps) and int(sweeps) >= 1):
        raise ValueError(
            f"friction_sweeps must be a whole number >= 1, got {sweeps!r}."
        )
    friction = coulomb(c)
    l0, dim = c["spacing"], int(c["dim"])
    if dim != 2:
        raise ValueError("block_stack is 2-D (dim=2).")
    length = setting_length(c, "floor_length")
    blocks, top, sizes = _stacked_blocks(c, l0, length)
    box = np.concatenate(blocks)
    body = np.concatenate([np.full(len(b), k) for k, b in enumerate(blocks)])
    height = whole_above(1.2 * top, l0)
    fluid = np.zeros((0, dim))
    if c["water_depth"] > 0:
        fluid, height = _tilted_water(c, box, length, "the blocks", top)
    walls, wall_kind = geometry.tank(
        [0.0, 0.0], [length, height], l0, layers=boundary_layers(c)
    )
    position = np.concatenate([fluid, box, walls])
    kind = np.concatenate(
        [
            np.full(len(fluid) + len(box), int(Kind.FLUID), np.int32),
            wall_kind,
        ]
    )
    owner = np.concatenate([np.full(len(fluid), -1), body, np.full(len(walls), -1)])
    scene = _body_scene(
        c, position, _domain([0.0, 0.0], [length, height], l0, top), kind
    )
    params = case_params(c, dim, velocity_scale(top, c["gravity"]))
    state = make_state(scene, position, kind)
    scene, params, state = add_rigid_bodies(
        scene,
        params,
        state,
        owner,
        density=c["density"] * c["density_ratio"],
        mu_static=c["mu_static"],
        mu_kinetic=c["mu_kinetic"],
        friction=friction,
        pressure="pairs",
        friction_sweeps=int(sweeps),
    )
    tilted = jnp.asarray(
        _tilted_gravity(dim, c["gravity"], float(c["angle"])), params.gravity.dtype
    )
    params = eqx.tree_at(lambda p: p.gravity, params, tilted)
    if c["settle"] > 0:
        state = _spun_up(scene, params, state, c["settle"], tilted)
    probes = block_probes(len(blocks))
    config = {
        **c,
        **sizes,
        "floor_length": length,
    }
    return Case("block_stack", scene, params, state, probes, float(c["t_end"]), config)


BLOCK_IMPACT = {
    "body": "rigid",
    "block_size": 2.5,
    "density_ratio": 1.0,
    "youngs_modulus": 1.0e6,
    "poisson_ratio": 0.48,
    "substeps": None,
    "contact": "auto",
    "velocity": 1.0,
    "gap": 0.1,
    "spacing": 0.1,
    "dim": 2,
    "gravity": 0.0,
    "t_end": 1.0,
}


def block_impact(**overrides) -> Case:
    """Seed 000 §8.4: a block (`block_size` square, `density_ratio` x `density`)
    moving at `velocity` straight down onto a fixed floor from `gap` above it, without
    gravity. The collision force is the floor's wall pressure summed over the contact
    face and the block's contact push on the floor (probe `wall_force`, N/m in
    2-D; `WallForce`); its time integral is the impulse, which
    lies between rho A v (plastic) and 2 rho A v (elastic rebound).

    `body` is "rigid" or "elastic" (`youngs_modulus`, `poisson_ratio`; `substeps`
    elastic sub-steps per step, None: the fewest within the elastic limit, 1: the
    seed's scheme, which refuses a step beyond the limit).

    Probes: `wall_force`, `block_y`, `block_velocity_y` (the body's centre and
    mean velocity); rigid also `block_force_y`, `block_impulse_y` (time integral
    of the force on the block).
    """
    c = resolve("block_impact", BLOCK_IMPACT, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    a = setting_length(c, "block_size")
    # A clearance: under half a spacing it opens to one (the least the lattice
    # holds apart), not refused like a body's size.
    gap = whole(c["gap"], l0) if c["gap"] > 0 else 0.0
    if c["dt"] == "adaptive" and c["dt_max"] is None:
        if not c["velocity"] != 0:
            raise ValueError(
                "velocity=0 leaves no velocity scale to derive the largest time step "
                "from; give `dt_max` (seconds) as well, or a non-zero `velocity`."
            )
        c = {**c, "dt_max": 0.005 * l0 / abs(c["velocity"])}
    side = whole(0.5 * a, l0)
    length = a + 2 * side
    across = [length] if dim == 3 else []
    box = geometry.block(
        [side] * (dim - 1) + [gap], [side + a] * (dim - 1) + [gap + a], l0
    )
    height = whole_above(gap + 1.2 * a, l0)
    walls, wall_kind = geometry.tank(
        [0.0] * dim, [length] + across + [height], l0, layers=boundary_layers(c)
    )
    domain = _domain([0.0] * dim, [length] + across + [height], l0, a)
    velocity = np.zeros(dim)
    velocity[-1] = -float(c["velocity"])
    lower = [side - 2 * l0] * (dim - 1) + [-l0]
    upper = [side + a + 2 * l0] * (dim - 1) + [0.0]
    wall_force = WallForce("wall_force", tuple(lower), tuple(upper), l0)
    config = {**c, "block_size": a, "gap": gap}
    if c["body"] == "elastic":
        scene, params, state = _elastic_block(
            c, box, walls, wall_kind, domain, velocity
        )
        probes = (
            wall_force,
            ElasticValue("block_y", 0, "centre", dim - 1),
            ElasticValue("block_velocity_y", 0, "velocity", dim - 1),
        )
        return Case("block_impact", scene, params, state, probes, c["t_end"], config)
    scene, params, state = _body_case(
        {**c, "friction": None},
        np.zeros((0, dim)),
        box,
        walls,
        wall_kind,
        domain,
        max(abs(c["velocity"]), 1e-9),
        None,
    )
    rigid = state.rigid
    member = np.asarray(rigid.body) >= 0
    state = eqx.tree_at(
        lambda s: (s.velocity, s.rigid.velocity),
        state,
        (
            jnp.where(
                jnp.asarray(member)[:, None],
                jnp.asarray(velocity, state.velocity.dtype),
                state.velocity,
            ),
            jnp.asarray(velocity[None, :], state.velocity.dtype),
        ),
    )
    probes = (
        wall_force,
        BodyValue("block_y", 0, "centre", dim - 1),
        BodyValue("block_velocity_y", 0, "velocity", dim - 1),
        BodyValue("block_force_y", 0, "force", dim - 1),
        BodyValue("block_impulse_y", 0, "impulse", dim - 1),
    )
    return Case("block_impact", scene, params, state, probes, float(c["t_end"]), config)


def _elastic_block(
    config, box, walls, wall_kind, domain, velocity, speed=None, **friction
):
    """Scene, params and state for one elastic block moving at `velocity` among
    walls (`speed`: the velocity scale, the block's speed if None; `friction`:
    `add_elastic_bodies`' friction arguments)."""
    dim = box.shape[1]
    position = np.concatenate([box, walls])
    kind = np.concatenate([np.full(len(box), int(Kind.FLUID), np.int32), wall_kind])
    scene = _body_scene(config, position, domain, kind)
    if speed is None:
        speed = max(float(np.abs(velocity).max()), 1e-9)
    params = case_params(config, dim, speed)
    moving = np.zeros_like(position)
    moving[: len(box)] = velocity
    state = make_state(scene, position, kind, velocity=moving)
    body = np.concatenate([np.zeros(len(box), int), np.full(len(walls), -1)])
    substeps = config["substeps"]
    return add_elastic_bodies(
        scene,
        params,
        state,
        body,
        youngs_modulus=config["youngs_modulus"],
        poisson_ratio=config["poisson_ratio"],
        density=config["density"] * config["density_ratio"],
        substeps=None if substeps is None else int(substeps),
        contact=config["contact"],
        **friction,
    )


DAM_BREAK_BOX = {
    "column_width": 0.146,
    "column_height": 0.292,
    "tank_length": 0.584,
    "tank_height": 0.438,
    "box_width": 0.04,
    "box_height": 0.02,
    "box_x": 0.3,
    "density_ratio": 0.5,
    "mu_static": 0.5,
    "mu_kinetic": None,
    "spacing": 0.00365,
    "dim": 2,
    "t_end": 0.35,
}


def dam_break_box(**overrides) -> Case:
    """The 2-D dam break of `dam_break` with a rigid box (`box_width` x `box_height`,
    `density_ratio` x the water's density) resting on the dry floor with its left
    face at `box_x`; the surge lifts it and carries it into the right wall. Friction
    with the floor and walls uses `mu_static` / `mu_kinetic`.

    Probes: `front`, `box_x`, `box_y`, `box_velocity_x`, `box_force_x` (fluid and
    contact force, gravity excluded), `box_impulse_x` (its time integral),
    `right_wall_force` (pressure on the right wall).

    The box reaches the wall at ~0.27 s at 2.4 m/s (adaptive steps at the default
    Courant 0.1 follow it: its track is within 1 cm and 0.07 m/s of Courant 0.02's,
    at a quarter of the steps). `t_end` is 0.35 s: after that the run-up jet
    leaves the domain (raise `domain_margin` and `tank_height` to go on).
    """
    c = resolve("dam_break_box", DAM_BREAK_BOX, overrides)
    l0 = c["spacing"]
    if int(c["dim"]) != 2:
        raise ValueError("dam_break_box is 2-D only (dim=2).")
    a, h = setting_length(c, "column_width"), setting_length(c, "column_height")
    length, height = setting_length(c, "tank_length"), setting_length(c, "tank_height")
    bw, bh = setting_length(c, "box_width"), setting_length(c, "box_height")
    x0 = setting_length(c, "box_x")
    if not (a < x0 and x0 + bw < length):
        raise ValueError(
            f"The box must lie between the column and the right wall: box_x "
            f"({x0:g} m on the lattice) must exceed column_width ({a:g} m) and "
            f"box_x + box_width ({x0 + bw:g} m) stay below tank_length ({length:g} m)."
        )
    fluid = geometry.block([0.0, 0.0], [a, h], l0)
    box = geometry.block([x0, 0.0], [x0 + bw, bh], l0)
    walls, wall_kind = geometry.tank(
        [0.0, 0.0], [length, height], l0, layers=boundary_layers(c)
    )
    scene, params, state = _body_case(
        c,
        fluid,
        box,
        walls,
        wall_kind,
        _domain([0.0, 0.0], [length, height], l0, 0.5 * height),
        velocity_scale(h, c["gravity"]),
        None,
    )
    probes = (
        FrontPosition("front", 0.0, 0.0, 2 * l0, l0, int(round(length / l0)) // 2 + 1),
        BodyValue("box_x", 0, "centre", 0),
        BodyValue("box_y", 0, "centre", 1),
        BodyValue("box_velocity_x", 0, "velocity", 0),
        BodyValue("box_force_x", 0, "force", 0),
        BodyValue("box_impulse_x", 0, "impulse", 0),
        WallForce("right_wall_force", (length, 0.0), (length + l0, height), l0),
    )
    config = {**c, "box_width": bw, "box_height": bh, "box_x": x0}
    t_end = float(c["t_end"])
    return Case("dam_break_box", scene, params, state, probes, t_end, config)
