"""Fluid solvers and their stages."""

from ._cg import SolveInfo as SolveInfo
from ._cg import solve_spd as solve_spd
from ._correct import pressure_gradient as pressure_gradient
from ._explicit import Explicit as Explicit
from ._open import Inflow as Inflow
from ._open import InflowParams as InflowParams
from ._open import Outflow as Outflow
from ._open import apply_inflow as apply_inflow
from ._open import apply_outflow as apply_outflow
from ._predict import collide as collide
from ._predict import predict_velocity as predict_velocity
from ._pressure import pressure_system as pressure_system
from ._pressure import solve_pressure as solve_pressure
from ._semi_implicit import AbstractSolver as AbstractSolver
from ._semi_implicit import SemiImplicit as SemiImplicit
from ._source import AbstractSource as AbstractSource
from ._source import DensitySource as DensitySource
from ._source import MixedSource as MixedSource
from ._surface import FreeSurface as FreeSurface
from ._surface import detect_surface as detect_surface
