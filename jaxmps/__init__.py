"""jaxmps: a differentiable Moving Particle Semi-implicit (MPS) solver in JAX.

Everyday API, re-exported here:

- building a simulation: `scenes` (built-in cases), `make_scene`, `make_params`,
  `make_state`, `add_rigid_bodies`, `add_elastic_bodies`, `add_grains`,
  `add_porous_regions` (with `PorousRegion`; `fill_pores` thins the water of
  regions with a porosity), `schemes` (discretisation
  presets);
- its three objects: `Scene` (static), `Params` (differentiable), `State` (the
  scan carry), with `Discretisation` and `Kind`;
- running it: `step`, `simulate` (and `lower_simulate` to time compilation),
  `run` (host driver with run files), `with_neighbour_lists` /
  `without_neighbour_lists` for loops of `step`; `Trajectory`, `Frame`, `frame`,
  `StepInfo`, `Result`; adaptive time steps: `Adaptive`, `time_step`,
  `time_step_limits`, `StepHistory`;
- sweeps and fits: `sweep`, `calibrate`; over devices and processes:
  `member_mesh`, `start_processes`, and `sweep_run` (a run file per member);
  one run over several devices: `shard_particles` (XLA's partitioning) and
  `simulate_slabs` (explicit scenes, slabs with a halo: `SlabRun`,
  `SlabRunError`, `slab_halo`);
- the two pressure stages `SemiImplicit`, `Explicit` and the gradients
  `CorrectedGradient`, `StandardGradient`, with the weight `MPSWeight`;
- the coupling records between fluid and body stages: `Coupling`, `FluidLoad`.

Subpackages are public namespaces for the rest: `neighbours`, `operators`,
`fluid`, `bodies`, `geometry`, `io`, `scenes`, `calibration`.
"""

from . import bodies as bodies
from . import calibration as calibration
from . import fluid as fluid
from . import geometry as geometry
from . import io as io
from . import neighbours as neighbours
from . import operators as operators
from . import scenes as scenes
from . import schemes as schemes
from ._build import add_elastic_bodies as add_elastic_bodies
from ._build import add_rigid_bodies as add_rigid_bodies
from ._build import make_params as make_params
from ._build import make_scene as make_scene
from ._build import make_state as make_state
from ._build_grains import add_grains as add_grains
from ._coupling import Coupling as Coupling
from ._coupling import FluidLoad as FluidLoad
from ._devices import member_mesh as member_mesh
from ._devices import shard_particles as shard_particles
from ._devices import start_processes as start_processes
from ._driver import RunInterrupted as RunInterrupted
from ._driver import run as run
from ._params import Params as Params
from ._regions import PorousRegion as PorousRegion
from ._regions import add_porous_regions as add_porous_regions
from ._regions import fill_pores as fill_pores
from ._result import Result as Result
from ._result import StepInfo as StepInfo
from ._scene import Scene as Scene
from ._simulate import Frame as Frame
from ._simulate import StepHistory as StepHistory
from ._simulate import Trajectory as Trajectory
from ._simulate import frame as frame
from ._simulate import lower_simulate as lower_simulate
from ._simulate import simulate as simulate
from ._slabs import SlabRun as SlabRun
from ._slabs import SlabRunError as SlabRunError
from ._slabs import simulate_slabs as simulate_slabs
from ._slabs import slab_halo as slab_halo
from ._state import State as State
from ._step import step as step
from ._step import time_step as time_step
from ._step import time_step_limits as time_step_limits
from ._step import with_neighbour_lists as with_neighbour_lists
from ._step import without_neighbour_lists as without_neighbour_lists
from ._stepping import Adaptive as Adaptive
from ._sweep_files import SweepRunResult as SweepRunResult
from ._sweep_files import grid as grid
from ._sweep_files import sweep_run as sweep_run
from ._types import Kind as Kind
from .calibration import calibrate as calibrate
from .calibration import sweep as sweep
from .fluid import Explicit as Explicit
from .fluid import SemiImplicit as SemiImplicit
from .operators import CorrectedGradient as CorrectedGradient
from .operators import Discretisation as Discretisation
from .operators import MPSWeight as MPSWeight
from .operators import StandardGradient as StandardGradient

__version__ = "0.1.0"
