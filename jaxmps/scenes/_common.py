"""Shared construction of the built-in scenes: overrides, tanks, Scene/State."""

import inspect
import math
from typing import Any

import numpy as np

from .. import geometry, schemes
from .._build import make_params, make_scene, make_state
from .._stepping import Adaptive
from .._types import Kind
from ..fluid import Explicit, Jacobi, Multigrid, SemiImplicit
from ..fluid._explicit import WALL_PRESSURES

SOLVERS = ("semi_implicit", "explicit")
SCHEMES = ("standard", "high_accuracy", "standard_mps", "standard_ds")
PRECONDITIONERS = {"multigrid": Multigrid, "jacobi": Jacobi}


def _default(function, name: str) -> Any:
    """The default of `function`'s argument `name`."""
    return inspect.signature(function).parameters[name].default


def _preconditioner_name(preconditioner) -> str:
    return next(
        name
        for name, kind in PRECONDITIONERS.items()
        if isinstance(preconditioner, kind)
    )


# Overrides every scene accepts, with their defaults (None: scene-specific). The
# physical and solver defaults are read from where they are written: `make_params`
# and `SemiImplicit`.
COMMON = {
    "solver": "semi_implicit",
    "scheme": "standard",
    "dt": "adaptive",
    "dt_max": None,
    "dt_min": None,
    "relaxation_step": None,
    "viscosity": _default(make_params, "viscosity"),
    "density": _default(make_params, "density"),
    "gravity": _default(make_params, "gravity"),
    "beta": _default(make_params, "beta"),
    "sound_speed": _default(make_params, "sound_speed"),
    "rtol": SemiImplicit.rtol,
    "max_iterations": SemiImplicit.max_iterations,
    "preconditioner": _preconditioner_name(SemiImplicit.preconditioner),
    "wall_pressure": Explicit.wall_pressure,
    "variable_density": SemiImplicit.variable_density,
    "max_neighbours": None,
    "candidate_capacity": None,
    "courant": Adaptive.courant,
    "domain_margin": None,
    "escape_limit": None,
    # porous damping regions (`_porous.accepts_porous`)
    "porous_kappa": None,
    "porous_box": None,
    "porous_direction": "vertical",
    "porous_drag": 0.0,
    "porous_porosity": 1.0,
    "porous_regions": None,
}


def _renamed(overrides: dict[str, Any]) -> dict[str, Any]:
    """Settings of earlier versions: `cell_capacity` (particles per cell) became
    `candidate_capacity` (particles in a particle's stencil cells). Run files of
    earlier versions store it as None (the default), which is dropped; a value has
    no equivalent and is refused with the new name. `dt=None` (a fixed step from
    the Courant rule) became `dt="adaptive"`."""
    if overrides.get("dt", "") is None:
        overrides = {**overrides, "dt": "adaptive"}
    if "cell_capacity" not in overrides:
        return overrides
    overrides = dict(overrides)
    if overrides.pop("cell_capacity") is not None:
        raise ValueError(
            "cell_capacity was replaced by candidate_capacity, the most particles "
            "in the neighbour-search cells around one particle (not in one cell); "
            "set `candidate_capacity=...`, or leave it to the default."
        )
    return overrides


def resolve(name: str, specific: dict[str, Any], overrides: dict[str, Any]) -> dict:
    """Merge defaults and overrides; unknown names are an error listing valid ones."""
    defaults = {**COMMON, **specific}  # a scene may change a common default
    overrides = _renamed(overrides)
    unknown = sorted(set(overrides) - set(defaults))
    if unknown:
        raise ValueError(
            f"Unknown parameter(s) {unknown} for scene '{name}'. Valid parameters: "
            f"{', '.join(sorted(defaults))}."
        )
    for key, value in overrides.items():
        _check_type(name, key, defaults[key], value)
        _check_range(name, key, value)
        _check_choice(name, key, value)
    # Numbers as Python numbers: whole for counts, float for the rest (a value
    # given as `--set gravity=0` or numpy.float32(9.81) is the float 0.0, 9.81).
    overrides = {
        key: value
        if value is None or isinstance(value, (bool, np.bool_, str))
        else int(value)
        if key in _WHOLE
        else float(value)
        for key, value in overrides.items()
    }
    config = {**defaults, **overrides}
    if config["solver"] not in SOLVERS:
        raise ValueError(
            f"solver={config['solver']!r} is not available; valid: {SOLVERS}."
        )
    if config["scheme"] not in SCHEMES:
        raise ValueError(
            f"scheme={config['scheme']!r} is not available; valid: {SCHEMES}."
        )
    if config["preconditioner"] not in PRECONDITIONERS:
        raise ValueError(
            f"preconditioner={config['preconditioner']!r} is not available; valid: "
            f"{tuple(PRECONDITIONERS)}."
        )
    if config["wall_pressure"] not in WALL_PRESSURES:
        raise ValueError(
            f"wall_pressure={config['wall_pressure']!r} is not available; valid: "
            f"{WALL_PRESSURES}."
        )
    if config["wall_pressure"] != Explicit.wall_pressure and config["solver"] != (
        "explicit"
    ):
        raise ValueError(
            f"wall_pressure={config['wall_pressure']!r} is an option of the explicit "
            "solver (the semi-implicit one solves the walls' pressure); use "
            "solver=explicit."
        )
    if config["variable_density"] and config["solver"] != "semi_implicit":
        raise ValueError(
            "variable_density=True is an option of the semi-implicit solver's "
            "pressure equation (the explicit solver's pressure is a state "
            "equation); use solver=semi_implicit or leave variable_density off."
        )
    if config["scheme"] != "standard" and config["solver"] != "semi_implicit":
        raise ValueError(
            f"scheme={config['scheme']!r} is a semi-implicit scheme; use "
            "solver=semi_implicit, or scheme=standard with solver=explicit."
        )
    if config.get("dim", 2) not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {config.get('dim')}.")
    if not config["spacing"] > 0:
        raise ValueError("spacing must be positive.")
    return config


class Range:
    """The values a numeric setting accepts: finite, between `low` and `high`
    (either bound open or closed; None for no bound)."""

    def __init__(self, low=None, high=None, *, open_low=False, open_high=False):
        self.low, self.high = low, high
        self.open_low, self.open_high = open_low, open_high

    def __contains__(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        if self.low is not None and not (
            value > self.low if self.open_low else value >= self.low
        ):
            return False
        return self.high is None or (
            value < self.high if self.open_high else value <= self.high
        )

    def __str__(self) -> str:
        def shown(bound):
            return str(int(bound)) if float(bound).is_integer() else f"{bound:g}"

        bounded = self.low is not None and self.high is not None
        if bounded and not (self.low == 0 and self.high >= 1000):
            left = "(" if self.open_low else "["
            right = ")" if self.open_high else "]"
            return f"finite, in {left}{shown(self.low)}, {shown(self.high)}{right}"
        if self.low == 0:
            text = "positive and finite" if self.open_low else "finite and >= 0"
        elif self.low is not None:
            text = f"finite and {'>' if self.open_low else '>='} {shown(self.low)}"
        else:
            text = "finite"
        if self.high is not None:
            text += f", {'below' if self.open_high else 'at most'} {shown(self.high)}"
        return text


_FINITE = Range()
_POSITIVE = Range(0, open_low=True)
_NON_NEGATIVE = Range(0)
# Lengths [m] up to 10 km: beyond, products like spacing^2 leave float range long
# before any scene makes sense.
_LENGTH = Range(0, 1e4, open_low=True)
_OFFSET = Range(0, 1e4)
_COUNT = Range(1, 2**31 - 1)
_ANGLE = Range(-90, 90, open_low=True, open_high=True)

# The accepted values of every numeric scene setting (a number not listed here
# must be finite). None, where a setting's default is None, means "derived" and is
# not checked here.
RULES = {
    # common settings
    "dt": _POSITIVE,
    "dt_max": _POSITIVE,
    "dt_min": _POSITIVE,
    "relaxation_step": _POSITIVE,
    "viscosity": _NON_NEGATIVE,
    "density": _POSITIVE,
    "gravity": _NON_NEGATIVE,
    "beta": Range(0, 1, open_low=True),
    "sound_speed": _POSITIVE,
    "rtol": Range(0, 1, open_low=True, open_high=True),
    "max_iterations": _COUNT,
    "max_neighbours": _COUNT,
    "candidate_capacity": _COUNT,
    "courant": Range(0, 1, open_low=True),
    "domain_margin": _OFFSET,
    "bed_depth": _OFFSET,
    "escape_limit": Range(0, 2**31 - 1),
    # lengths [m]
    "spacing": _LENGTH,
    "width": _LENGTH,
    "depth": _LENGTH,
    "tank_length": _LENGTH,
    "tank_height": _LENGTH,
    "tank_width": _LENGTH,
    "column_width": _LENGTH,
    "column_height": _LENGTH,
    "box_width": _LENGTH,
    "box_height": _LENGTH,
    "block_size": _LENGTH,
    "block_height": _LENGTH,
    "base_width": _LENGTH,
    "water_depth": _OFFSET,
    "floor_length": _LENGTH,
    "bed_length": _LENGTH,
    "bottom_width": _LENGTH,
    "inflow_depth": _LENGTH,
    "box_x": _OFFSET,
    "gauge_x": Range(-1e4, 1e4),
    "gap": _OFFSET,
    "weir_height": _OFFSET,
    "tail_depth": _LENGTH,
    "crest_length": _LENGTH,
    "step_height": _OFFSET,
    "apron_length": _OFFSET,
    "reach_length": _OFFSET,
    "transition_length": _OFFSET,
    "bed_lowering": _OFFSET,
    "scour_length": _OFFSET,
    "scour_depth": _OFFSET,
    "scour_centre": _LENGTH,
    "scour_exposure": _OFFSET,
    "movable_length": _OFFSET,
    "movable_start": _OFFSET,
    "movable_depth": _LENGTH,
    "block_length": _LENGTH,
    "block_gap": _OFFSET,
    "initial_draft": _OFFSET,
    "bilge_radius": _OFFSET,
    "centre_of_gravity": _OFFSET,
    "gyration": _POSITIVE,
    "amplitude": _OFFSET,
    "length": _LENGTH,
    "thickness": _LENGTH,
    "wavelength": _LENGTH,
    "span": _LENGTH,
    "end_length": _OFFSET,
    "stroke": _OFFSET,
    "sea_depth": _LENGTH,
    "sea_length": _LENGTH,
    "quay_crest": _LENGTH,
    "quay_length": _LENGTH,
    "tsunami_height": _LENGTH,  # a wave that draws down first is not modelled
    "ship_beam": _LENGTH,
    "ship_length": _LENGTH,
    "ship_draft": _LENGTH,
    "ship_height": _LENGTH,
    "ship_gap": _LENGTH,
    "building_depth": _LENGTH,
    "building_length": _LENGTH,
    "building_height": _LENGTH,
    "building_distance": _LENGTH,
    "gauge_spacing": _LENGTH,
    "offshore_gauge": _LENGTH,
    "reservoir_length": _LENGTH,
    "reservoir_depth": _LENGTH,
    "pressure_spacing": _LENGTH,
    # angles [degrees] and slopes
    "angle": _ANGLE,
    "heel": _ANGLE,
    "slope": _NON_NEGATIVE,
    "beach_slope": _POSITIVE,
    # times [s], rates and counts
    "t_end": _POSITIVE,
    "rise_time": _POSITIVE,
    "hold_time": _NON_NEGATIVE,
    "fall_time": _POSITIVE,
    "scale": Range(0, 10, open_low=True),
    "gauges": Range(1, 64),
    "pressure_gauges": Range(0, 64),
    "settle": _NON_NEGATIVE,
    "release_time": _NON_NEGATIVE,
    "frequency": _NON_NEGATIVE,
    "wave_period": _POSITIVE,
    "ramp_periods": _NON_NEGATIVE,
    "discharge": _POSITIVE,
    "velocity": _FINITE,  # signed: towards the floor when positive
    "pool": Range(0, 2**31 - 1),
    "substeps": _COUNT,
    "blocks": Range(1, 64),
    "friction_sweeps": Range(1, 10000),
    "block_rows": Range(0, 1000),
    # ratios and coefficients
    "density_ratio": _POSITIVE,
    "block_density": _POSITIVE,
    "mu_static": _NON_NEGATIVE,
    "mu_kinetic": _NON_NEGATIVE,
    "youngs_modulus": _POSITIVE,
    "poisson_ratio": Range(-1, 0.5, open_low=True, open_high=True),
    "solid_density": _POSITIVE,
    "tip_velocity": _FINITE,
    "end_velocity": _FINITE,
    "plate_depth": _POSITIVE,
    "plate_length": _LENGTH,
    "porous_kappa": _POSITIVE,
    "porous_drag": _NON_NEGATIVE,
    "porous_porosity": Range(0, 1, open_low=True),
    # grains
    "grain_diameter": _LENGTH,
    "grain_density": _POSITIVE,
    "friction": _NON_NEGATIVE,
    "restitution": Range(0, 1, open_low=True),
    "lift": _NON_NEGATIVE,
    "rolling": _NON_NEGATIVE,
    "stiffness": _POSITIVE,
    "contact_capacity": _COUNT,
    "mode_number": _COUNT,
    "polydispersity": Range(0, 1, open_high=True),
    "seed": Range(0, 2**31 - 1),
    "release_depth": _LENGTH,
    "drop_height": _LENGTH,
}
# Settings that are not one number: checked where they are read
# (`_porous.accepts_porous`, `jaxmps.add_porous_regions`).
STRUCTURED = ("porous_box", "porous_regions")


def _check_range(scene: str, key: str, value: Any) -> None:
    """A numeric override lies in the range `RULES` gives for its name (ValueError
    naming the setting and the range)."""
    if value is None or isinstance(value, (bool, np.bool_, str)):
        return
    rule = RULES.get(key, _FINITE)
    try:
        inside = float(value) in rule
    except OverflowError:
        inside = False
    if not inside:
        raise ValueError(
            f"{key} must be {rule}, got {value!r} (a setting of scene '{scene}')."
        )


# Parameters counted in whole numbers (None: derived).
_WHOLE = (
    "dim",
    "max_iterations",
    "max_neighbours",
    "candidate_capacity",
    "pool",
    "escape_limit",
    "substeps",
    "contact_capacity",
    "seed",
    "blocks",
    "block_rows",
    "gauges",
    "pressure_gauges",
    "mode_number",
)


def _whole(value) -> bool:
    """Whether a number is a whole number (False for nan, inf and beyond floats)."""
    try:
        return math.isfinite(float(value)) and float(value) == int(value)
    except OverflowError:
        return False


# The words a scene's word settings accept (the common ones, `solver`, `scheme`,
# `preconditioner` and `wall_pressure`, are checked in `resolve`). Checked on every
# override, also where the scene's other settings leave it unused (`contact` of a
# rigid body, `friction_normal` of a flume without blocks), so that a misspelt word
# is refused rather than ignored. A scene may accept fewer (`floating_box`'s
# `body_pressure` has no "auto") and says so itself.
_CHOICES = {
    "body": ("rigid", "elastic"),
    "ship_body": ("rigid", "elastic"),
    "contact": ("auto", "pressure", "push"),
    "layout": ("stack", "row"),
    "friction_normal": ("reaction", "pressure", "submerged_weight"),
    "body_pressure": ("auto", "fluid", "pairs"),
    "target": ("dimple", "particle"),
    "slope_wall": ("staircase", "type1", "type2"),
    "plate_walls": ("both", "left", "right"),
    "end": ("wall", "beach"),
}


def _check_choice(scene: str, key: str, value: Any) -> None:
    """A word setting's override is one of its words (`_CHOICES`)."""
    valid = _CHOICES.get(key)
    if valid is not None and value not in valid:
        raise ValueError(
            f"{key}={value!r} is not a choice of scene '{scene}'; valid: "
            f"{', '.join(valid)}."
        )


def _check_type(scene: str, key: str, default: Any, value: Any) -> None:
    """An override has the type of its default: a flag, a word, or a number (whole
    for counts); None only where the default is None (derived)."""
    number = isinstance(value, (int, float, np.integer, np.floating)) and not (
        isinstance(value, (bool, np.bool_))
    )
    if key == "dt":
        ok = number or value == "adaptive"
        want = "'adaptive' or a number of seconds"
    elif key == "relaxation_step":
        ok = number or value is None or value == "calm"
        want = "'calm', a number of seconds or None (per step)"
    elif isinstance(default, bool):
        ok, want = isinstance(value, (bool, np.bool_)), "true or false"
    elif isinstance(default, str):
        ok, want = isinstance(value, str), "a word"
    elif key in _WHOLE:
        ok = (number and _whole(value)) or (default is None and value is None)
        want = "a whole number" + (" or None" if default is None else "")
    else:
        ok = number or (default is None and value is None)
        want = "a number" + (" or None (derived)" if default is None else "")
    if not ok:
        raise ValueError(
            f"Parameter {key!r} of scene '{scene}' expects {want}, got {value!r} "
            f"({type(value).__name__}); e.g. `--set {key}={default}`."
            if default is not None
            else f"Parameter {key!r} of scene '{scene}' expects {want}, got {value!r} "
            f"({type(value).__name__})."
        )


# The Courant number of the largest step on the scene's velocity scale: the step
# seed 000 takes (0.2 l0 / sqrt(2 g H)); a calm flow takes it, a violent one less.
CALM_COURANT = 0.2


def default_dt(config: dict, velocity_scale: float) -> float:
    """`Params.dt`: the `dt` setting when it is a number of seconds (fixed steps);
    under adaptive steps the largest step, the `dt_max` setting or else
    `CALM_COURANT` l0 / U for the scene's velocity scale U, for the explicit
    solver also at most 0.4 l0 / c (as in seed 002): the step a calm flow takes,
    shortened by the flow's own limits when it is not (`jaxmps.Adaptive`, with
    the `courant` setting on the flow's largest speed)."""
    if config["dt"] != "adaptive":
        bounds = [k for k in ("dt_max", "dt_min") if config[k] is not None]
        if bounds:
            raise ValueError(
                f"{' and '.join(bounds)} bound adaptive steps, but dt={config['dt']:g} "
                "s fixes the step; give dt='adaptive' (the default) or drop "
                f"{' and '.join(bounds)}."
            )
        return float(config["dt"])
    dt = _largest_step(config, velocity_scale)
    if config["dt_min"] is not None and not config["dt_min"] < dt:
        raise ValueError(
            f"dt_min={config['dt_min']:g} s must be below the largest step "
            f"{dt:.4g} s (the `dt_max` setting, or the scene's own); lower `dt_min`."
        )
    return dt


def _largest_step(config: dict, velocity_scale: float) -> float:
    """The `dt_max` setting, or the Courant rule for the scene's velocity scale."""
    if config["dt_max"] is not None:
        return float(config["dt_max"])
    if not velocity_scale > 0:
        raise ValueError(
            f"gravity={config['gravity']!r} leaves no velocity scale to derive the "
            "largest time step from; give `dt_max` (seconds) as well, or a "
            "positive `gravity`."
        )
    dt = calm_step(config, velocity_scale)
    if config["solver"] == "explicit":
        dt = min(dt, 0.4 * config["spacing"] / config["sound_speed"])
    if not 0 < dt < math.inf:  # a velocity scale that overflowed
        raise ValueError(
            f"gravity={config['gravity']!r} m/s^2 with spacing="
            f"{config['spacing']!r} m gives a largest time step of {dt!r} s "
            f"(velocity scale {velocity_scale!r} m/s); give a physical `gravity`, "
            "or `dt_max` (seconds)."
        )
    return float(dt)


def discretisation(config: dict) -> schemes.Scheme:
    """The `Scheme` of the `solver` and `scheme` settings (with the pressure-solve
    settings `rtol`, `max_iterations`, `preconditioner`)."""
    if config["solver"] == "explicit":
        return schemes.explicit(Explicit(wall_pressure=config["wall_pressure"]))
    solver = SemiImplicit(
        rtol=config["rtol"],
        max_iterations=int(config["max_iterations"]),
        preconditioner=PRECONDITIONERS[config["preconditioner"]](),
        variable_density=bool(config["variable_density"]),
    )
    if config["scheme"] == "high_accuracy":
        return schemes.high_accuracy(solver)
    if config["scheme"] == "standard_mps":
        return schemes.standard_mps(solver)
    if config["scheme"] == "standard_ds":
        return schemes.standard(solver, dynamic_stabilisation=True)
    return schemes.standard(solver)


def boundary_layers(config: dict) -> int:
    """Wall + dummy layers that give a wall particle a full neighbourhood."""
    return geometry.layers_for(discretisation(config).r_e)


def time_stepping(config: dict) -> Adaptive | None:
    """`Scene.time_step` of the `dt` setting: adaptive steps at the `courant`
    setting (bounded below by `dt_min`), or None for a fixed `dt` in seconds."""
    if config["dt"] != "adaptive":
        return None
    return Adaptive(courant=config["courant"], dt_min=config["dt_min"])


# The share of a scene's fluid particles that may leave the domain (spray, water
# over a wall) before a run ends, unless the `escape_limit` setting says.
ESCAPE_SHARE = 0.1


def case_scene(
    config: dict,
    position,
    domain,
    kind,
    *,
    candidate_capacity=None,
    capacity=None,
    crowding: float = 1.0,
):
    """The Scene of a built-in case: the discretisation of the `solver` and `scheme`
    settings, the `max_neighbours` / `candidate_capacity` settings
    (`candidate_capacity` here is the scene's own default when the setting is
    None), adaptive or fixed steps by the `dt` setting, and the `escape_limit`
    setting (default: `ESCAPE_SHARE` of the fluid particles of `kind`).
    `crowding` scales the default neighbour and candidate margins: how many times
    the fluid lattice's density may gather in one place (grains hidden from the
    fluid share its space)."""
    escape = config["escape_limit"]
    if escape is None:
        fluid = int(np.sum(np.asarray(kind) == int(Kind.FLUID)))
        escape = math.ceil(ESCAPE_SHARE * fluid)
    setting = config["candidate_capacity"]
    return make_scene(
        position,
        config["spacing"],
        domain,
        capacity=capacity,
        max_neighbours=config["max_neighbours"],
        candidate_capacity=candidate_capacity if setting is None else setting,
        neighbour_margin=2.0 * crowding,
        candidate_margin=1.5 * crowding,
        scheme=discretisation(config),
        time_step=time_stepping(config),
        escape_limit=escape,
    )


def tank_case(
    config: dict,
    fluid_lower,
    fluid_upper,
    tank_lower,
    tank_upper,
    velocity_scale: float,
    more_fluid=(),
):
    """Fluid block in an open tank of walls and dummies: scene, params, state, extra.
    `more_fluid`: further (lower, upper) fluid blocks on the same lattice."""
    l0 = config["spacing"]
    layers = boundary_layers(config)
    blocks = [(fluid_lower, fluid_upper), *more_fluid]
    fluid = np.concatenate([geometry.block(lo, up, l0) for lo, up in blocks])
    walls, wall_kind = geometry.tank(tank_lower, tank_upper, l0, layers=layers)
    position = np.concatenate([fluid, walls])
    kind = np.concatenate([np.full(len(fluid), int(Kind.FLUID), np.int32), wall_kind])
    height = float(tank_upper[-1] - tank_lower[-1])
    margin = config["domain_margin"]
    margin = 0.5 * height if margin is None else float(margin)
    lower = np.asarray(tank_lower, float) - layers * l0 - 2 * l0
    upper = np.asarray(tank_upper, float) + layers * l0 + 2 * l0
    upper[-1] = tank_upper[-1] + margin
    scene = case_scene(config, position, (lower, upper), kind)
    params = case_params(config, position.shape[1], velocity_scale)
    state = make_state(scene, position, kind)
    return scene, params, state, dict(walls=walls, wall_kind=wall_kind)


def case_params(config: dict, dim: int, velocity_scale: float):
    """Params from the common settings, dt from the Courant rule for
    `velocity_scale` (or the `dt` setting), and the pressure source's density
    relaxation per step of dt (the `relaxation_step` setting None), per the step
    a calm flow takes at this resolution and velocity scale whatever `dt` or
    `dt_max` say ("calm"; per step where there is no velocity scale), or per a
    number of seconds (`Params.relaxation_step`)."""
    relax = config["relaxation_step"]
    if relax == "calm":
        relax = calm_step(config, velocity_scale)
    return make_params(
        dim,
        dt=default_dt(config, velocity_scale),
        density=config["density"],
        viscosity=config["viscosity"],
        gravity=config["gravity"],
        beta=config["beta"],
        sound_speed=config["sound_speed"],
        relaxation_step=relax,
    )


def calm_step(config: dict, velocity_scale: float) -> float | None:
    """`CALM_COURANT` l0 / U: the largest step of a calm flow at the scene's
    resolution and velocity scale U [s] (None where U is 0)."""
    if not velocity_scale > 0:
        return None
    return CALM_COURANT * config["spacing"] / velocity_scale


def nearest_wall(walls: np.ndarray, wall_kind: np.ndarray, point) -> tuple[int, ...]:
    """Index (into the state, walls follow the fluid) of the wall particle nearest
    `point`; returned as a tuple for `PressureAt`. Caller adds the fluid offset."""
    candidates = np.where(wall_kind == int(Kind.WALL))[0]
    d = np.linalg.norm(walls[candidates] - np.asarray(point), axis=1)
    return (int(candidates[np.argmin(d)]),)


def check_gauge(overrides: dict, c: dict, length: float) -> None:
    """Refuse a `gauge_x` the user placed outside a tank of `length` [m]; the
    default one (placed for the default tank) is left where it is when only the
    tank is shortened."""
    if "gauge_x" in overrides and not 0 <= c["gauge_x"] <= length:
        raise ValueError(
            f"gauge_x={c['gauge_x']:g} m lies outside the tank [0, {length:g}] m "
            "(tank_length); the gauge would read no water."
        )


def whole_above(value: float, spacing: float) -> float:
    """A length rounded up to a whole number of spacings (itself where it is
    one): room above a body, whatever its size."""
    count = value / spacing
    if abs(count - round(count)) < 1e-9 * max(1.0, abs(count)):
        return value
    return math.ceil(count) * spacing


def whole(value: float, spacing: float) -> float:
    """Round a length to a whole number of spacings (at least one).

    Raises:
        ValueError: naming `spacing`, where the count is beyond any index (a
            spacing so small that the length holds more than 2^31 of them).
    """
    count = value / spacing
    if not count <= 2**31:
        raise ValueError(
            f"spacing={spacing:g} m divides a length of {value:g} m into "
            f"{count:.3g} particles, more than any scene can index; raise spacing."
        )
    return max(1, round(count)) * spacing


def setting_length(c: dict, key: str) -> float:
    """The length setting `key` as the scene builds it: a whole number of spacings.

    Raises:
        ValueError: naming `key` and `spacing`, where the setting is under half a
            spacing (it would be built one spacing long, over twice what was
            asked), or as `whole`.
    """
    value, spacing = float(c[key]), c["spacing"]
    if value < 0.5 * spacing:
        raise ValueError(
            f"{key}={value:g} m is under half the particle spacing ({spacing:g} m), "
            f"so the scene would build it one spacing long: refine `spacing` (to "
            f"{2 * value:g} m or less) or lengthen `{key}`."
        )
    return whole(value, spacing)


def velocity_scale(height: float, gravity: float) -> float:
    """sqrt(2 g h), the free-fall speed over `height` (0 without gravity)."""
    return math.sqrt(2.0 * max(gravity, 0.0) * height)


def floating_sound_speed(config: dict, depth: float) -> float:
    """The `sound_speed` setting, or where it is None (derived), the equation of
    state's sound speed for a body floating in water `depth` deep: ten times the
    free-fall speed over the depth (Mach 0.1), which compresses the water at the
    bottom by g H / c^2 = 0.5 %, and not below the common 10 m/s.

    # Choice: a floating body is rigid (its lattice stays at n0) in water the
    # equation of state compresses by g z / c^2 at depth z, and the buoyancy the
    # explicit solver gives it depends on that mismatch: at c = 10 m/s in 0.2 m of
    # water (2 % at the bottom) boxes floated 0.4-0.5 l0 too high by the pressure's
    # surface at both l0 = B/10 and B/20 (validation/floating_draft.py); at 0.5 %
    # within 0.1 l0. The cost is the step, 0.4 l0 / c: twice as many steps here.
    """
    if config["sound_speed"] is not None:
        return float(config["sound_speed"])
    return max(
        float(_default(make_params, "sound_speed")),
        10.0 * velocity_scale(depth, config["gravity"]),
    )
