"""Built-in scenes: `jaxmps.scenes.<name>(**overrides) -> Case`."""

from ._bodies import BLOCK_IMPACT as _BLOCK_IMPACT
from ._bodies import BLOCK_STACK as _BLOCK_STACK
from ._bodies import DAM_BREAK_BOX as _DAM_BREAK_BOX
from ._bodies import FLOATING_BOX as _FLOATING_BOX
from ._bodies import FRICTION_TILT as _FRICTION_TILT
from ._bodies import block_impact as _block_impact
from ._bodies import block_stack as _block_stack
from ._bodies import dam_break_box as _dam_break_box
from ._bodies import floating_box as _floating_box
from ._bodies import friction_tilt as _friction_tilt
from ._case import Case as Case
from ._common import COMMON
from ._dam_break import DEFAULTS as _DAM_BREAK
from ._dam_break import dam_break as _dam_break
from ._elastic import ELASTIC_BAR as _ELASTIC_BAR
from ._elastic import ELASTIC_CANTILEVER as _ELASTIC_CANTILEVER
from ._elastic import ELASTIC_GATE as _ELASTIC_GATE
from ._elastic import ELASTIC_PLATE as _ELASTIC_PLATE
from ._elastic import bar_theory as bar_theory
from ._elastic import cantilever_theory as cantilever_theory
from ._elastic import elastic_bar as _elastic_bar
from ._elastic import elastic_cantilever as _elastic_cantilever
from ._elastic import elastic_gate as _elastic_gate
from ._elastic import elastic_plate as _elastic_plate
from ._elastic import oscillation_mean as oscillation_mean
from ._elastic import plate_theory as plate_theory
from ._flume import DEFAULTS as _FLUME
from ._flume import flume as _flume
from ._grains import GRAIN_DROP as _GRAIN_DROP
from ._grains import GRAIN_SETTLING as _GRAIN_SETTLING
from ._grains import GRANULAR_COLLAPSE as _GRANULAR_COLLAPSE
from ._grains import column_packing as column_packing
from ._grains import grain_drop as _grain_drop
from ._grains import grain_settling as _grain_settling
from ._grains import granular_collapse as _granular_collapse
from ._grains import settling_velocity as settling_velocity
from ._hydrostatic import DEFAULTS as _HYDROSTATIC
from ._hydrostatic import hydrostatic as _hydrostatic
from ._hydrostatic import hydrostatic_pressure as hydrostatic_pressure
from ._porous import accepts_porous
from ._probes import AbstractProbe as AbstractProbe
from ._probes import BedLowering as BedLowering
from ._probes import BodiesMoved as BodiesMoved
from ._probes import BodyPressure as BodyPressure
from ._probes import BodyValue as BodyValue
from ._probes import ColumnDepth as ColumnDepth
from ._probes import DisplacedDepth as DisplacedDepth
from ._probes import Displacement as Displacement
from ._probes import ElasticAmplitude as ElasticAmplitude
from ._probes import ElasticValue as ElasticValue
from ._probes import FlowVelocity as FlowVelocity
from ._probes import FluidCount as FluidCount
from ._probes import FluidPressureNear as FluidPressureNear
from ._probes import FrontPosition as FrontPosition
from ._probes import GrainHeight as GrainHeight
from ._probes import GrainRunout as GrainRunout
from ._probes import GrainValue as GrainValue
from ._probes import ModeAmplitude as ModeAmplitude
from ._probes import PressureAt as PressureAt
from ._probes import PressureLevel as PressureLevel
from ._probes import RunUp as RunUp
from ._probes import StripLevel as StripLevel
from ._probes import WallForce as WallForce
from ._probes import WallPressure as WallPressure
from ._probes import WaterLevel as WaterLevel
from ._probes import observe_probes as observe_probes
from ._scour import LOCAL_SCOUR as _LOCAL_SCOUR
from ._scour import MEASURED_SCOUR as MEASURED_SCOUR
from ._scour import local_scour as _local_scour
from ._sloshing import SLOSHING_TANK as _SLOSHING_TANK
from ._sloshing import STANDING_WAVE as _STANDING_WAVE
from ._sloshing import natural_frequency as natural_frequency
from ._sloshing import sloshing_tank as _sloshing_tank
from ._sloshing import standing_wave as _standing_wave
from ._sloshing import standing_wave_period as standing_wave_period
from ._tsunami import TSUNAMI_QUAY as _TSUNAMI_QUAY
from ._tsunami import tsunami_quay as _tsunami_quay
from ._washout import BLOCK_WASHOUT as _BLOCK_WASHOUT
from ._washout import MEASURED_HOLES as MEASURED_HOLES
from ._washout import block_washout as _block_washout
from ._washout import critical_feed as critical_feed
from ._washout import scour_hole as scour_hole
from ._wave_tank import DEFAULTS as _WAVE_TANK
from ._wave_tank import wave_tank as _wave_tank

# Every scene takes the porous-region settings (`_porous.SETTINGS`) as well.
block_impact = accepts_porous(_block_impact)
block_stack = accepts_porous(_block_stack)
block_washout = accepts_porous(_block_washout)
dam_break = accepts_porous(_dam_break)
dam_break_box = accepts_porous(_dam_break_box)
elastic_bar = accepts_porous(_elastic_bar)
elastic_cantilever = accepts_porous(_elastic_cantilever)
elastic_gate = accepts_porous(_elastic_gate)
elastic_plate = accepts_porous(_elastic_plate)
floating_box = accepts_porous(_floating_box)
flume = accepts_porous(_flume)
friction_tilt = accepts_porous(_friction_tilt)
grain_drop = accepts_porous(_grain_drop)
grain_settling = accepts_porous(_grain_settling)
granular_collapse = accepts_porous(_granular_collapse)
hydrostatic = accepts_porous(_hydrostatic)
local_scour = accepts_porous(_local_scour)
sloshing_tank = accepts_porous(_sloshing_tank)
standing_wave = accepts_porous(_standing_wave)
tsunami_quay = accepts_porous(_tsunami_quay)
wave_tank = accepts_porous(_wave_tank)

_REGISTRY = {
    "block_impact": (block_impact, _BLOCK_IMPACT),
    "block_stack": (block_stack, _BLOCK_STACK),
    "block_washout": (block_washout, _BLOCK_WASHOUT),
    "friction_tilt": (friction_tilt, _FRICTION_TILT),
    "dam_break": (dam_break, _DAM_BREAK),
    "dam_break_box": (dam_break_box, _DAM_BREAK_BOX),
    "elastic_bar": (elastic_bar, _ELASTIC_BAR),
    "elastic_cantilever": (elastic_cantilever, _ELASTIC_CANTILEVER),
    "elastic_gate": (elastic_gate, _ELASTIC_GATE),
    "elastic_plate": (elastic_plate, _ELASTIC_PLATE),
    "floating_box": (floating_box, _FLOATING_BOX),
    "flume": (flume, _FLUME),
    "grain_drop": (grain_drop, _GRAIN_DROP),
    "grain_settling": (grain_settling, _GRAIN_SETTLING),
    "granular_collapse": (granular_collapse, _GRANULAR_COLLAPSE),
    "hydrostatic": (hydrostatic, _HYDROSTATIC),
    "local_scour": (local_scour, _LOCAL_SCOUR),
    "sloshing_tank": (sloshing_tank, _SLOSHING_TANK),
    "standing_wave": (standing_wave, _STANDING_WAVE),
    "tsunami_quay": (tsunami_quay, _TSUNAMI_QUAY),
    "wave_tank": (wave_tank, _WAVE_TANK),
}


def available() -> dict[str, dict]:
    """Scene names and their parameters with defaults (None: derived)."""
    return {name: {**COMMON, **d} for name, (_, d) in sorted(_REGISTRY.items())}


def stored_settings(name: str, config: dict) -> dict:
    """The settings of scene `name` in a case's stored `config` (a run file's),
    without the values the scene derived and stored beside them (the flume's
    `apron_end`, a standing wave's period...), so that `build(name, **...)`
    rebuilds the case."""
    valid = available().get(name, {})
    return {key: value for key, value in config.items() if key in valid}


def build(name: str, **overrides) -> Case:
    """Build scene `name` with parameter overrides (ValueError on unknown names)."""
    if name not in _REGISTRY:
        raise ValueError(
            f"Unknown scene '{name}'. Available scenes: {', '.join(sorted(_REGISTRY))}."
        )
    return _REGISTRY[name][0](**overrides)
