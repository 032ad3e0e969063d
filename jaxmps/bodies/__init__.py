"""Bodies carried by the flow: rigid bodies with contact and friction."""

from ._friction import AbstractNormalForce as AbstractNormalForce
from ._friction import ContactPressure as ContactPressure
from ._friction import ContactReaction as ContactReaction
from ._friction import Coulomb as Coulomb
from ._friction import SubmergedWeight as SubmergedWeight
from ._rigid import RigidBodies as RigidBodies
from ._rigid import advance_bodies as advance_bodies
from ._rigid import body_pressure_gradient as body_pressure_gradient
from ._rigid import contact_partners as contact_partners
from ._rigid import is_body as is_body
from ._rigid import particle_density as particle_density
from ._rigid import with_contact as with_contact
from ._rigid import without_internal_pairs as without_internal_pairs
from ._state import RigidState as RigidState
