"""Case: everything a built-in scene provides to run it."""

from typing import Any

import equinox as eqx

from .._params import Params
from .._scene import Scene
from .._state import State
from ._probes import AbstractProbe


class Case(eqx.Module):
    """A ready-to-run simulation.

    Attributes:
        name: the scene's registered name.
        scene, params, state: as for `jaxmps.simulate`.
        probes: measurements saved by `jaxmps.run` under /probes.
        t_end: default simulated time [s].
        config: every override value used to build the case (JSON-serialisable), so
            that a run file can rebuild it.
    """

    name: str
    scene: Scene
    params: Params
    state: State
    probes: tuple[AbstractProbe, ...]
    t_end: float
    config: dict[str, Any]
