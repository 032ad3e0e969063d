"""Bodies carried by the flow. Each kind is a body model (`AbstractBodyModel`)
that the step couples to the fluid through two records (`jaxmps.Coupling` in,
`jaxmps.FluidLoad` out): rigid bodies with contact and friction, elastic
bodies, and DEM grains."""

from .._state import ElasticState as ElasticState
from .._state import GrainState as GrainState
from .._state import RigidState as RigidState
from ._base import AbstractBodyModel as AbstractBodyModel
from ._elastic import ElasticBodies as ElasticBodies
from ._elastic import ElasticResponse as ElasticResponse
from ._elastic import corrective_matrices as corrective_matrices
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
from ._grain_laws import Contacts as Contacts
from ._grain_laws import contact_forces as contact_forces
from ._grain_laws import damping_ratio as damping_ratio
from ._grain_laws import drag_coefficient as drag_coefficient
from ._grain_laws import fluid_force as fluid_force
from ._grain_laws import rule_step as rule_step
from ._grain_laws import rule_stiffness as rule_stiffness
from ._grain_laws import seed_contact_parameters as seed_contact_parameters
from ._grain_laws import sphere_volume as sphere_volume
from ._grains import Grains as Grains
from ._rigid import RigidBodies as RigidBodies
from ._rigid import is_body as is_body
from ._setup import body_indices as body_indices
from ._setup import orientations as orientations
from ._setup import per_body as per_body
from ._setup import per_body_rows as per_body_rows
from ._setup import rigid_state as rigid_state
