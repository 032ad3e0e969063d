"""Bodies carried by the flow. Each kind is a body model (`AbstractBodyModel`)
that the step couples to the fluid through two records (`jaxmps.Coupling` in,
`jaxmps.FluidLoad` out); rigid bodies with contact and friction are the first."""

from .._state import RigidState as RigidState
from ._base import AbstractBodyModel as AbstractBodyModel
from ._friction import AbstractNormalForce as AbstractNormalForce
from ._friction import Contact as Contact
from ._friction import ContactPressure as ContactPressure
from ._friction import ContactReaction as ContactReaction
from ._friction import Coulomb as Coulomb
from ._friction import SubmergedWeight as SubmergedWeight
from ._rigid import RigidBodies as RigidBodies
from ._rigid import is_body as is_body
from ._setup import body_indices as body_indices
from ._setup import orientations as orientations
from ._setup import per_body as per_body
from ._setup import per_body_rows as per_body_rows
from ._setup import rigid_state as rigid_state
