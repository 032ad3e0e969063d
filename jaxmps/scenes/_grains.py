"""DEM grains (seed 002 §5): a grain settling in still water, and a dry granular
column collapsing on a rough floor."""

import math

import numpy as np

from .. import geometry
from .._build import make_state
from .._build_grains import add_grains
from .._types import Kind
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
from ._probes import GrainHeight, GrainRunout, GrainValue

# The material settings every grain scene takes (defaults: seed 002's friction
# tan 30 degrees; a restitution of 0.1, near the seed's critically damped
# contacts, which rebound not at all).
MATERIAL = {
    "grain_diameter": None,
    "grain_density": 2650.0,
    "friction": 0.577,
    "restitution": 0.1,
    "lift": 0.2,
    "rolling": 0.0,
    "stiffness": None,
    "contact_capacity": None,
    "substeps": None,
    "on_fluid": False,
}

GRAIN_SETTLING = {
    **MATERIAL,
    "width": 0.04,
    "depth": 0.05,
    "spacing": 0.002,
    "grain_density": 2250.0,
    "release_depth": None,
    "dim": 2,
    "t_end": 0.15,
}


def settling_velocity(
    diameter: float,
    grain_density: float,
    density: float = 1000.0,
    viscosity: float = 1e-6,
    gravity: float = 9.81,
) -> float:
    """The terminal velocity [m/s] of a sphere whose Schiller-Naumann drag 1/2
    rho (pi d^2 / 4) C_D(Re) v^2 balances its submerged weight (rho_s - rho) g
    pi d^3 / 6 (seed 002's test T7): the root of the monotone drag curve by
    bisection to round-off, in NumPy (independent of the model's own drag)."""
    weight = (grain_density - density) * gravity * math.pi / 6.0 * diameter**3
    if not weight > 0:
        raise ValueError("a grain must be denser than the fluid to settle.")

    def drag(v: float) -> float:
        reynolds = v * diameter / viscosity
        if reynolds > 1000.0:
            coefficient = 0.44
        else:
            coefficient = 24.0 / reynolds * (1.0 + 0.15 * reynolds**0.687)
        return 0.5 * density * math.pi / 4.0 * diameter**2 * coefficient * v * v

    low, high = 0.0, 1.0
    while drag(high) < weight:
        high *= 2.0
    for _ in range(200):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if drag(middle) < weight else (low, middle)
    return 0.5 * (low + high)


def _grain_case(c: dict, name: str, position, kind, grains, domain, scale: float):
    """Scene, params and state of a grain scene: the particles (`grains` marks the
    grains, which start as plain particles) and `add_grains` with the scene's
    material settings."""
    scene = case_scene(c, position, domain, kind)
    params = case_params(c, position.shape[1], scale)
    state = make_state(scene, position, kind)
    return add_grains(
        scene,
        params,
        state,
        grains,
        friction=c["friction"],
        restitution=c["restitution"],
        density=c["grain_density"],
        stiffness=c["stiffness"],
        lift=c["lift"],
        rolling=c["rolling"],
        diameter=c["grain_diameter"],
        contact_capacity=c["contact_capacity"],
        substeps=c["substeps"],
        on_fluid=c["on_fluid"],
    )


def grain_settling(**overrides) -> Case:
    """One grain released at rest in still water of `depth` in a tank of
    `width` (and `width` deep in 3-D), `release_depth` below the surface
    (default: three diameters), on the tank's centre line between two fluid
    particles. The grain is a sphere of `grain_diameter` (default: the spacing)
    and `grain_density`; the water flows through it (grains are hidden from the
    fluid) and drags it (`bodies.fluid_force`).

    Probes: `grain_velocity` (its vertical velocity, negative downwards),
    `grain_height` (its centre above the floor). `settling_velocity` gives the
    terminal velocity the drag law balances with the submerged weight.
    """
    c = resolve("grain_settling", GRAIN_SETTLING, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    d = l0 if c["grain_diameter"] is None else c["grain_diameter"]
    width, depth = setting_length(c, "width"), setting_length(c, "depth")
    release = 3.0 * d if c["release_depth"] is None else c["release_depth"]
    if not d <= release <= depth - d:
        raise ValueError(
            f"release_depth={release:g} m must put the grain under water: between "
            f"its diameter {d:g} m and depth - diameter {depth - d:g} m."
        )
    layers = boundary_layers(c)
    horizontal = [width] * (dim - 1)
    fluid = geometry.block([0.0] * dim, horizontal + [depth], l0)
    height = whole(1.25 * depth, l0)
    walls, wall_kind = geometry.tank(
        [0.0] * dim, horizontal + [height], l0, layers=layers
    )
    # On the centre line, between the lattice's sites (the fluid keeps all of
    # its particles: the grain is hidden from it).
    grain = np.asarray([[0.5 * width] * (dim - 1) + [depth - release]])
    position = np.concatenate([grain, fluid, walls])
    kind = np.concatenate(
        [np.full(1 + len(fluid), int(Kind.FLUID), np.int32), wall_kind]
    )
    lower = np.full(dim, -(layers + 2) * l0)
    upper = np.asarray(horizontal + [height], float) + (layers + 2) * l0
    upper[-1] = height + 0.5 * depth
    mask = np.zeros(len(position), bool)
    mask[0] = True
    scale = velocity_scale(depth, c["gravity"])
    scene, params, state = _grain_case(
        c, "grain_settling", position, kind, mask, (lower, upper), scale
    )
    config = {**c, "width": width, "depth": depth, "grain_diameter": d}
    return _one_grain("grain_settling", scene, params, state, config)


def _one_grain(name: str, scene, params, state, config: dict) -> Case:
    """The Case of a scene of one grain, with its probes `grain_height` and
    `grain_velocity` (vertical)."""
    dim = scene.dim
    probes = (
        GrainValue("grain_height", (0,), "position", dim - 1),
        GrainValue("grain_velocity", (0,), "velocity", dim - 1),
    )
    return Case(
        name=name,
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=float(config["t_end"]),
        config=config,
    )


GRAIN_DROP = {
    **MATERIAL,
    "drop_height": 0.03,
    "target": "dimple",
    "width": 0.05,
    "spacing": 0.005,
    "dim": 2,
    "t_end": 0.3,
}


def grain_drop(**overrides) -> Case:
    """One grain dropped in air from rest, its lowest point `drop_height` above
    the floor's wall particles' tops, over the dimple between two of them
    (`target="dimple"`: a stable valley, where it bounces straight up and down
    but meets the two at an angle, so that friction takes a part of each
    rebound) or right over one (`target="particle"`: a head-on impact, whose
    rebound leaves at the contact's restitution, but a perch the grain rolls
    off after a few bounces).

    Probes: `grain_height` (its centre above the floor's top), `grain_velocity`
    (vertical, negative downwards).
    """
    c = resolve("grain_drop", GRAIN_DROP, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    d = l0 if c["grain_diameter"] is None else c["grain_diameter"]
    width = setting_length(c, "width")
    if width < 2 * l0:
        raise ValueError("width must hold two floor particles: raise `width`.")
    top = whole(c["drop_height"] + 3 * d, l0)
    layers = boundary_layers(c)
    horizontal = [width] * (dim - 1)
    walls, wall_kind = geometry.tank([0.0] * dim, horizontal + [top], l0, layers=layers)
    # Floor particles sit at (i + 1/2) l0: between two, or on one.
    shift = 0.0 if c["target"] == "dimple" else 0.5 * l0
    middle = [round(0.5 * width / l0) * l0 + shift] * (dim - 1)
    grain = np.asarray([middle + [c["drop_height"] + 0.5 * d]])
    position = np.concatenate([grain, walls])
    kind = np.concatenate([[int(Kind.FLUID)], wall_kind]).astype(np.int32)
    lower = np.full(dim, -(layers + 2) * l0)
    upper = np.asarray(horizontal + [top], float) + (layers + 2) * l0
    mask = np.zeros(len(position), bool)
    mask[0] = True
    scale = velocity_scale(c["drop_height"] + d, c["gravity"])
    scene, params, state = _grain_case(
        c, "grain_drop", position, kind, mask, (lower, upper), scale
    )
    config = {**c, "width": width, "grain_diameter": d}
    return _one_grain("grain_drop", scene, params, state, config)


GRANULAR_COLLAPSE = {
    **MATERIAL,
    "column_width": 0.05,
    "column_height": 0.1,
    "floor_length": 0.3,
    "spacing": 0.005,
    "friction": 0.5,
    "polydispersity": 0.2,
    "seed": 0,
    "dim": 2,
    "t_end": 1.0,
}


def column_packing(
    width: float, height: float, diameter: float, polydispersity: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Grain centres and diameters of a 2-D column [0, width] x [0, height]: a
    hexagonal packing of sites `diameter` apart (rows sqrt(3)/2 d apart, every
    other one shifted by d/2), each grain of a diameter drawn uniformly from
    [(1 - polydispersity) d, d] (seeded): no two grains overlap, and the spread
    of sizes keeps the heap from crystallising."""
    d = diameter
    rows = int(math.floor((height - d) / (0.5 * math.sqrt(3.0) * d))) + 1
    centres = []
    for j in range(max(rows, 1)):
        shift = 0.5 * d if j % 2 else 0.0
        count = int(math.floor((width - d - shift) / d + 1e-9)) + 1
        y = 0.5 * d + j * 0.5 * math.sqrt(3.0) * d
        centres += [(0.5 * d + shift + i * d, y) for i in range(max(count, 0))]
    centres = np.asarray(centres, float)
    rng = np.random.default_rng(seed)
    sizes = d * (1.0 - polydispersity * rng.random(len(centres)))
    return centres, sizes


def granular_collapse(**overrides) -> Case:
    """A dry column of grains, `column_width` by `column_height`, against the
    left wall of a floor `floor_length` long, released at once (no gate) and
    spreading on the floor of wall particles (spheres of the spacing: a rough
    floor). The grains are a hexagonal packing of sites one `grain_diameter`
    (default: the spacing) apart with diameters spread by `polydispersity`
    (`column_packing`, `seed`). 2-D.

    Probes: `runout` (the deposit's reach from the left wall, `GrainRunout`)
    and `height` (its height at the wall). The aspect ratio is a = H0 / L0 of
    the column; the published 2-D laws compare (L_inf - L0) / L0 with it.
    """
    c = resolve("granular_collapse", GRANULAR_COLLAPSE, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    if dim != 2:
        raise ValueError("granular_collapse is 2-D; give dim=2.")
    d = l0 if c["grain_diameter"] is None else c["grain_diameter"]
    width, height = c["column_width"], c["column_height"]
    floor = setting_length(c, "floor_length")
    if not floor > width + d:
        raise ValueError(
            f"floor_length={floor:g} m must exceed column_width={width:g} m: the "
            "column spreads over the floor."
        )
    if not (width >= d and height >= d):
        raise ValueError(
            f"column_width and column_height must hold one grain of {d:g} m."
        )
    centres, sizes = column_packing(width, height, d, c["polydispersity"], c["seed"])
    layers = boundary_layers(c)
    top = whole(1.25 * height + d, l0)
    walls, wall_kind = geometry.tank([0.0, 0.0], [floor, top], l0, layers=layers)
    position = np.concatenate([centres, walls])
    kind = np.concatenate([np.full(len(centres), int(Kind.FLUID), np.int32), wall_kind])
    lower = np.full(2, -(layers + 2) * l0)
    upper = np.asarray([floor + (layers + 2) * l0, top + height])
    mask = np.zeros(len(position), bool)
    mask[: len(centres)] = True
    config = {**c, "grain_diameter": d, "floor_length": floor}
    config_material = {**c, "grain_diameter": sizes}
    scene, params, state = _grain_case(
        config_material,
        "granular_collapse",
        position,
        kind,
        mask,
        (lower, upper),
        velocity_scale(height, c["gravity"]),
    )
    probes = (
        GrainRunout("runout", 0.0, 0.0, 1.5 * d, d, int(math.ceil(floor / d)) // 2 + 1),
        GrainHeight("height", 0.0, 2.0 * d, 0.0),
    )
    return Case(
        name="granular_collapse",
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=float(c["t_end"]),
        config=config,
    )
