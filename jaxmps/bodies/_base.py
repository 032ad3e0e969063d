"""The interface of a body model: how bodies plug into the step."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Int, Shaped

from .._coupling import Coupling, FluidLoad
from .._params import Params
from .._state import State
from .._types import Positions, Scalar, Velocities
from ..operators import Discretisation, Pairs


class AbstractBodyModel(eqx.Module):
    """A kind of body carried by the flow (rigid bodies; elastic bodies and grains
    plug in the same way). A Scene holds each model it has in its own field
    (`Scene.rigid`, ...), with its parameters in the same field of `Params` and its
    sub-state in the same field of `State`; a Scene without the model holds None
    there, and its step compiles none of the model's code.

    A step asks every model present for its `coupling` before the fluid stages,
    lets it add its bodies' own forces to the prediction before the pressure
    (`predict`), and calls its `advance` after the fluid stages with what the
    fluid exerted (`FluidLoad`). A model
    never reads or writes the fluid's internals, nor the fluid a model's state.
    Everything else that is particular to a model is asked of it too: its checks
    before a run (`check`), what a saved frame holds of it (`observe`), and which
    particles it owns in a run file (`owner`).

    Attributes:
        name: the model's field in Scene, Params and State (e.g. "rigid"), and its
            sub-state's group in a run file's /state.
        frame_fields: the fields of its sub-state that each saved frame holds (a run
            file's /bodies/<field>), read by `observe`; unique across the models of
            a Scene.
    """

    name: eqx.AbstractClassVar[str]
    frame_fields: eqx.AbstractClassVar[tuple[str, ...]]

    @abc.abstractmethod
    def owner(self, state: State) -> Int[Array, " n"]:
        """The body each particle belongs to, -1 for none (numbered after the other
        models' bodies)."""

    @abc.abstractmethod
    def coupling(self, disc: Discretisation, params: Params, state: State) -> Coupling:
        """What this model imposes on the fluid for its particles: their mass
        density, which particles form one body and, for a deformable body, their
        unstrained number density (`Coupling.reference_density`)."""

    def predict(
        self,
        disc: Discretisation,
        params: Params,
        state: State,
        velocity: Velocities,
        position: Positions,
        reference_dt: Scalar | None = None,
        pairs: Pairs | None = None,
    ) -> tuple[State, Velocities, Positions]:
        """The tentative velocities u* and positions r* of the model's particles
        with its bodies' internal forces added, before the pressure stage (which
        then holds what they push against); by default unchanged. `velocity` and
        `position` are the fluid stages' u* and r* = r^k + dt u*; `reference_dt`
        the largest step (`Params.dt` of the run; `params.dt` is this step's);
        `pairs` the pair geometry at the step's start, r^k."""
        del disc, params, reference_dt, pairs
        return state, velocity, position

    @abc.abstractmethod
    def advance(
        self, disc: Discretisation, params: Params, state: State, load: FluidLoad
    ) -> State:
        """Advance the model's bodies by one step from the state the fluid stages
        left (body particles moved as fluid of their own density) and the
        `FluidLoad` of the step."""

    @abc.abstractmethod
    def check(self, params: Params, state: State) -> None:
        """Trace-time check that the model's parameters and sub-state fit it
        (ValueError naming the setting to change)."""

    def time_step_limit(
        self, disc: Discretisation, params: Params, state: State
    ) -> Scalar:
        """The largest dt this model's bodies are stable at [s] (an elastic body's
        P-wave, a grain contact's period); inf, the default, for none. Adaptive
        steps take a fraction of it (`jaxmps.Adaptive.stability`)."""
        del disc, state
        return jnp.asarray(jnp.inf, params.dt.dtype)

    def observe(self, state: State) -> dict[str, Shaped[Array, "..."]]:
        """What a saved frame holds of the model: its sub-state's `frame_fields`."""
        sub = getattr(state, self.name)
        return {field: getattr(sub, field) for field in self.frame_fields}
