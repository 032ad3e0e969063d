"""Still water in an open tank: the hydrostatic pressure test (seed 000 §10.2 #4)."""

from ._case import Case
from ._common import resolve, setting_length, tank_case, velocity_scale, whole
from ._probes import FluidPressureNear, PressureAt, WaterLevel

DEFAULTS = {"width": 0.2, "depth": 0.2, "spacing": 0.01, "dim": 2, "t_end": 1.0}


def hydrostatic(**overrides) -> Case:
    """Water of `depth` at rest in a tank of `width` (and `width` deep in 3-D).

    Probes: pressure at the bottom centre (fluid within 1.5 l0 of the first row), at
    mid-depth, of the bottom wall particle at the centre, and the water level.
    """
    c = resolve("hydrostatic", DEFAULTS, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    width, depth = setting_length(c, "width"), setting_length(c, "depth")
    height = whole(1.25 * depth, l0)
    horizontal = [width] * (dim - 1)
    scene, params, state, extra = tank_case(
        c,
        [0.0] * dim,
        horizontal + [depth],
        [0.0] * dim,
        horizontal + [height],
        velocity_scale(depth, c["gravity"]),
    )
    centre = [0.5 * width] * (dim - 1)
    n_fluid = int(state.active.sum()) - len(extra["walls"])
    from ._common import nearest_wall

    wall = nearest_wall(extra["walls"], extra["wall_kind"], centre + [-0.5 * l0])
    probes = (
        FluidPressureNear("pressure_bottom", tuple(centre + [0.5 * l0]), 1.5 * l0),
        FluidPressureNear("pressure_middle", tuple(centre + [0.5 * depth]), 1.5 * l0),
        PressureAt("pressure_wall_bottom", tuple(n_fluid + i for i in wall)),
        WaterLevel("water_level", centre[0], 0.0, l0),
    )
    config = {**c, "width": width, "depth": depth}
    return Case(
        name="hydrostatic",
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=float(c["t_end"]),
        config=config,
    )


def hydrostatic_pressure(case: Case, probe: str = "pressure_bottom") -> float:
    """The analytic value of a `FluidPressureNear` probe of a `hydrostatic` case [Pa]:
    rho |g| (H - y), the weight of the water above the mean initial height y of the
    probe's particles (H the water's depth). The semi-implicit schemes' pressure
    meets it (their surface particles carry the head of the water above them,
    `SemiImplicit.surface_head`); a solver that holds P = 0 at the surface
    particles' centres (the explicit one, or `surface_head=0`) reads up to about
    l0/2 of head below it."""
    import numpy as np

    from .._types import Kind

    near = next(p for p in case.probes if p.name == probe)
    if not isinstance(near, FluidPressureNear):
        raise ValueError(f"Probe {probe!r} is not a FluidPressureNear probe.")
    position = np.asarray(case.state.position, dtype=float)
    fluid = np.asarray(case.state.active) & (
        np.asarray(case.state.kind) == int(Kind.FLUID)
    )
    d2 = ((position - np.asarray(near.point)[None, :]) ** 2).sum(axis=-1)
    height = position[fluid & (d2 < near.radius**2), -1].mean()
    rho = float(case.params.density)
    g = float(np.linalg.norm(np.asarray(case.params.gravity)))
    return rho * g * (case.config["depth"] - height)
