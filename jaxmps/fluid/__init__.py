"""Fluid stages of a step and the two pressure stages (semi-implicit, explicit).

The step (`jaxmps.step`) runs them in order: `predict` (viscosity, gravity), the
porous damping (`damp`), the `CollisionGuard`, `advect` to r*, `detect_surface`,
the pressure stage (a `SemiImplicit` Poisson solve or the `Explicit` equation of state),
`pressure_force`, `accelerate` and the `DynamicStabilisation`; wall motion, inflow
and outflow act on the boundaries around them.
"""

from .._params import HarmonicParams as HarmonicParams
from .._params import InflowParams as InflowParams
from .._params import PorousParams as PorousParams
from .._params import StrokeParams as StrokeParams
from ._cg import SolveInfo as SolveInfo
from ._cg import solve_spd as solve_spd
from ._correct import accelerate as accelerate
from ._correct import pressure_force as pressure_force
from ._correct import pressure_gradient as pressure_gradient
from ._explicit import Explicit as Explicit
from ._motion import AbstractMotionLaw as AbstractMotionLaw
from ._motion import Harmonic as Harmonic
from ._motion import PrescribedMotion as PrescribedMotion
from ._motion import Tabulated as Tabulated
from ._motion import move_walls as move_walls
from ._open import Inflow as Inflow
from ._open import Outflow as Outflow
from ._open import apply_inflow as apply_inflow
from ._open import apply_outflow as apply_outflow
from ._open import inflow_boundary as inflow_boundary
from ._open import retire as retire
from ._porous import DIRECTIONS as DIRECTIONS
from ._porous import PorousRegions as PorousRegions
from ._porous import damp as damp
from ._porous import direction_axis as direction_axis
from ._porous import lowest_porosity as lowest_porosity
from ._porous import pore_weight as pore_weight
from ._porous import pore_weights as pore_weights
from ._porous import porosity_field as porosity_field
from ._porous import resistance_factor as resistance_factor
from ._precondition import AbstractPreconditioner as AbstractPreconditioner
from ._precondition import Jacobi as Jacobi
from ._precondition import Multigrid as Multigrid
from ._precondition import PressureSystem as PressureSystem
from ._predict import CollisionGuard as CollisionGuard
from ._predict import advect as advect
from ._predict import is_mobile as is_mobile
from ._predict import predict as predict
from ._pressure import assemble_pressure_system as assemble_pressure_system
from ._pressure import pressure_system as pressure_system
from ._pressure import solve_pressure as solve_pressure
from ._semi_implicit import SemiImplicit as SemiImplicit
from ._solver import AbstractPressureSolver as AbstractPressureSolver
from ._solver import PressureInputs as PressureInputs
from ._solver import PressureSolution as PressureSolution
from ._source import AbstractCompensation as AbstractCompensation
from ._source import AbstractSource as AbstractSource
from ._source import DensitySource as DensitySource
from ._source import DynamicCompensation as DynamicCompensation
from ._source import HigherOrderSource as HigherOrderSource
from ._source import MixedSource as MixedSource
from ._source import SourceInputs as SourceInputs
from ._source import density_rate as density_rate
from ._stabilise import DynamicStabilisation as DynamicStabilisation
from ._surface import FreeSurface as FreeSurface
from ._surface import detect_surface as detect_surface
