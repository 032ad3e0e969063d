"""Built-in scenes: `jaxmps.scenes.<name>(**overrides) -> Case`."""

from ._case import Case as Case
from ._common import COMMON
from ._dam_break import DEFAULTS as _DAM_BREAK
from ._dam_break import dam_break as dam_break
from ._flume import DEFAULTS as _FLUME
from ._flume import flume as flume
from ._hydrostatic import DEFAULTS as _HYDROSTATIC
from ._hydrostatic import hydrostatic as hydrostatic
from ._probes import AbstractProbe as AbstractProbe
from ._probes import FluidPressureNear as FluidPressureNear
from ._probes import FrontPosition as FrontPosition
from ._probes import PressureAt as PressureAt
from ._probes import StripLevel as StripLevel
from ._probes import WaterLevel as WaterLevel
from ._probes import observe_probes as observe_probes
from ._wave_tank import DEFAULTS as _WAVE_TANK
from ._wave_tank import wave_tank as wave_tank

_REGISTRY = {
    "dam_break": (dam_break, _DAM_BREAK),
    "flume": (flume, _FLUME),
    "hydrostatic": (hydrostatic, _HYDROSTATIC),
    "wave_tank": (wave_tank, _WAVE_TANK),
}


def available() -> dict[str, dict]:
    """Scene names and their parameters with defaults (None: derived)."""
    return {name: {**d, **COMMON} for name, (_, d) in sorted(_REGISTRY.items())}


def build(name: str, **overrides) -> Case:
    """Build scene `name` with parameter overrides (ValueError on unknown names)."""
    if name not in _REGISTRY:
        raise ValueError(
            f"Unknown scene '{name}'. Available scenes: {', '.join(sorted(_REGISTRY))}."
        )
    return _REGISTRY[name][0](**overrides)
