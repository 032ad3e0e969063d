"""The interface of a body model: how bodies plug into the step."""

import abc

import equinox as eqx

from .._coupling import Coupling, FluidLoad
from .._params import Params
from .._state import State
from ..operators import Discretisation


class AbstractBodyModel(eqx.Module):
    """A kind of body carried by the flow (rigid bodies; elastic bodies and grains
    plug in the same way). A Scene holds each model it has in its own field
    (`Scene.rigid`, ...), with its parameters in the same field of `Params` and its
    sub-state in the same field of `State`; a Scene without the model holds None
    there, and its step compiles none of the model's code.

    A step asks every model present for its `coupling` before the fluid stages, and
    calls its `advance` after them with what the fluid exerted (`FluidLoad`). A model
    never reads or writes the fluid's internals, nor the fluid a model's state.

    Attributes:
        name: the model's field in Scene, Params and State (e.g. "rigid").
    """

    name: eqx.AbstractClassVar[str]

    @abc.abstractmethod
    def coupling(self, params: Params, state: State) -> Coupling:
        """What this model imposes on the fluid for its particles: their mass
        density and which particles form one body."""

    @abc.abstractmethod
    def advance(
        self, disc: Discretisation, params: Params, state: State, load: FluidLoad
    ) -> State:
        """Advance the model's bodies by one step from the state the fluid stages
        left (body particles moved as fluid of their own density) and the
        `FluidLoad` of the step."""
