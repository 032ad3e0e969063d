"""State: the evolving arrays of a simulation, exactly the scan carry."""

import equinox as eqx
from jaxtyping import Array, Bool, Float, Int

from ._result import Result
from .bodies._state import RigidState
from .neighbours import NeighbourCache


class State(eqx.Module):
    """Fixed-capacity particle state. Arrays only; its structure never changes.

    Attributes:
        time: simulated time [s].
        step: number of steps taken.
        position: particle positions [m], shape (n, d).
        velocity: particle velocities [m/s], shape (n, d).
        pressure: particle pressures [Pa] (gauge; 0 on the free surface), shape (n,).
        kind: particle kind, a `jaxmps.Kind` value, shape (n,).
        active: whether the slot holds a live particle, shape (n,). Inactive slots are
            the pool: they are masked out of every sum and every neighbour search.
        result: the first failure of the run so far, or `Result.successful`.
        rigid: the rigid bodies' sub-state, present exactly when the Scene has
            rigid bodies.
        neighbours: the neighbour lists carried to the next step, or None (a new
            search at the start of every step). `simulate` adds it for the rollout
            (when `Scene.neighbour_skin` > 0) and removes it from what it returns
            and observes; a State a user builds or receives holds None.
    """

    time: Float[Array, ""]
    step: Int[Array, ""]
    position: Float[Array, "n d"]
    velocity: Float[Array, "n d"]
    pressure: Float[Array, " n"]
    kind: Int[Array, " n"]
    active: Bool[Array, " n"]
    result: Result
    rigid: RigidState | None = None
    neighbours: NeighbourCache | None = None
