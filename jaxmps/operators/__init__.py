"""MPS discrete operators: pure functions of pair geometry and particle fields."""

from ._density import number_density as number_density
from ._discretisation import Discretisation as Discretisation
from ._gradient import AbstractGradient as AbstractGradient
from ._gradient import CorrectedGradient as CorrectedGradient
from ._gradient import MinimumPressureGradient as MinimumPressureGradient
from ._gradient import StandardGradient as StandardGradient
from ._gradient import SymmetricGradient as SymmetricGradient
from ._laplacian import AbstractLaplacian as AbstractLaplacian
from ._laplacian import HigherOrderLaplacian as HigherOrderLaplacian
from ._laplacian import StandardLaplacian as StandardLaplacian
from ._laplacian import laplacian as laplacian
from ._laplacian import pair_laplacian as pair_laplacian
from ._pairs import Pairs as Pairs
from ._pairs import make_pairs as make_pairs
from ._weight import AbstractWeight as AbstractWeight
from ._weight import EMPSGradientWeight as EMPSGradientWeight
from ._weight import EMPSWeight as EMPSWeight
from ._weight import MPSWeight as MPSWeight
from ._weight import WendlandWeight as WendlandWeight
from ._weight import lattice_offsets as lattice_offsets
from ._weight import lattice_sum as lattice_sum
from ._weight import reference_constants as reference_constants
