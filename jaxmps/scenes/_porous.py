"""Porous damping regions as settings of every built-in scene."""

import functools

from .._regions import PorousRegion, add_porous_regions, fill_pores
from ._case import Case
from ._common import _check_range

# The settings, with their defaults (also listed in `_common.COMMON`): one region
# from `porous_kappa` (s) and `porous_box` (x0,y0[,z0],x1,y1[,z1]), its
# `porous_direction`, quadratic `porous_drag` (1/m) and `porous_porosity` (the
# share open to water); any number of regions
# from `porous_regions` (a list of `PorousRegion` or of dicts of its fields).
SETTINGS = {
    "porous_kappa": None,
    "porous_box": None,
    "porous_direction": "vertical",
    "porous_drag": 0.0,
    "porous_porosity": 1.0,
    "porous_regions": None,
}


def accepts_porous(scene_function):
    """`scene_function(**overrides) -> Case` taking the porous settings as well:
    the case is built without them, the regions added
    (`jaxmps.add_porous_regions`) and the fluid in regions with a porosity thinned
    to it (`jaxmps.fill_pores`); the case's config records them, so that a run
    file rebuilds the same scene."""

    @functools.wraps(scene_function)
    def build(**overrides) -> Case:
        settings = {key: overrides.pop(key) for key in SETTINGS if key in overrides}
        case = scene_function(**overrides)
        regions = _regions(case.name, {**SETTINGS, **settings}, case.scene.dim)
        config = {**case.config, **SETTINGS, **settings}
        if not regions:
            return Case(
                case.name,
                case.scene,
                case.params,
                case.state,
                case.probes,
                case.t_end,
                config,
            )
        scene, params = add_porous_regions(case.scene, case.params, case.state, regions)
        state = fill_pores(scene, case.state)
        config["porous_regions"] = (
            None
            if settings.get("porous_regions") is None
            else [PorousRegion.of(r).as_dict() for r in settings["porous_regions"]]
        )
        return Case(case.name, scene, params, state, case.probes, case.t_end, config)

    return build


def _regions(name: str, c: dict, dim: int) -> list[PorousRegion]:
    """The regions the settings describe (ValueError naming a setting)."""
    listed = c["porous_regions"]
    if listed is not None and not isinstance(listed, (list, tuple)):
        raise ValueError(
            f"porous_regions of scene '{name}' must be a list of regions "
            f"(PorousRegion or dicts), got {type(listed).__name__}."
        )
    regions = [PorousRegion.of(r) for r in (listed or ())]
    kappa, box = c["porous_kappa"], c["porous_box"]
    if kappa is None and box is None:
        changed = [
            k
            for k in ("porous_direction", "porous_drag", "porous_porosity")
            if c[k] != SETTINGS[k]
        ]
        if changed:
            raise ValueError(
                f"{', '.join(changed)} of scene '{name}' need a region: give "
                "porous_kappa and porous_box as well."
            )
        return regions
    if kappa is None or box is None:
        missing = "porous_kappa" if kappa is None else "porous_box"
        raise ValueError(
            f"A porous region of scene '{name}' needs porous_kappa (s) and "
            f"porous_box; {missing} is missing."
        )
    if not isinstance(c["porous_direction"], str):
        raise ValueError(
            f"porous_direction of scene '{name}' must be a word (x, y, z, "
            f"vertical, all), got {c['porous_direction']!r}."
        )
    for key in ("porous_kappa", "porous_drag", "porous_porosity"):
        _check_range(name, key, c[key])
    region = PorousRegion(
        box=_corners(box, dim),
        kappa=kappa,
        direction=c["porous_direction"],
        drag=c["porous_drag"],
        porosity=c["porous_porosity"],
    )
    return [region, *regions]


def _corners(box, dim: int):
    """(lower, upper) of a `porous_box` given as "x0,y0,x1,y1" (command line), as
    2 d numbers, or as two corners."""
    if isinstance(box, str):
        try:
            box = [float(v) for v in box.split(",")]
        except ValueError:
            raise ValueError(
                f"porous_box must be {2 * dim} comma-separated numbers "
                f"(x0,y0{',z0' if dim == 3 else ''},x1,y1{',z1' if dim == 3 else ''}),"
                f" got {box!r}."
            ) from None
    if (
        isinstance(box, (list, tuple))
        and len(box) == 2 * dim
        and all(not isinstance(v, (list, tuple)) for v in box)
    ):
        return tuple(box[:dim]), tuple(box[dim:])
    if isinstance(box, (list, tuple)) and len(box) == 2:
        return tuple(box)
    raise ValueError(
        f"porous_box must be {2 * dim} numbers x0,y0{',z0' if dim == 3 else ''},"
        f"x1,y1{',z1' if dim == 3 else ''} or two corners, got {box!r}."
    )
