"""Bodies carried by the flow. Each kind is a body model (`AbstractBodyModel`)
that the step couples to the fluid through two records (`jaxmps.Coupling` in,
`jaxmps.FluidLoad` out): rigid bodies with contact and friction, and elastic
bodies."""

from .._state import ElasticState as ElasticState
from .._state import RigidState as RigidState
from ._base import AbstractBodyModel as AbstractBodyModel
from ._elastic import ElasticBodies as ElasticBodies
from ._elastic import ElasticResponse as ElasticResponse
from ._elastic import elastic_response as elastic_response
from ._elastic import elastic_stress as elastic_stress
from ._elastic import lame as lame
from ._elastic import pressure_speed as pressure_speed
from ._elastic import shear_speed as shear_speed
from ._elastic_setup import elastic_state as elastic_state
from ._elastic_setup import reference_neighbours as reference_neighbours
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
