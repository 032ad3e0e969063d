"""Calibration against measured curves, and vmapped parameter sweeps."""

from ._decay import fit_damped_oscillation as fit_damped_oscillation
from ._fields import field_names as field_names
from ._fit import Bounded as Bounded
from ._fit import CalibrationResult as CalibrationResult
from ._fit import Curve as Curve
from ._fit import Identity as Identity
from ._fit import Log as Log
from ._fit import calibrate as calibrate
from ._fit import curve_loss as curve_loss
from ._sweep import SweepResult as SweepResult
from ._sweep import batch_params as batch_params
from ._sweep import sweep as sweep
