"""Shared type aliases and the particle-kind enumeration.

Dimension names used in annotations: `n` particles (capacity), `k` neighbour slots,
`d` spatial dimension, `t` saved frames.
"""

import enum

from jaxtyping import Array, Bool, Float, Int

Scalar = Float[Array, ""]
Vector = Float[Array, " d"]
Positions = Float[Array, "n d"]
Velocities = Float[Array, "n d"]
Field = Float[Array, " n"]
Mask = Bool[Array, " n"]
Kinds = Int[Array, " n"]
Indices = Int[Array, "n k"]
PairMask = Bool[Array, "n k"]
PairField = Float[Array, "n k"]
# Pair vectors as one (n, k) array per axis, not an (n, k, d) array (`_numerics`
# says why).
PairVectors = tuple[Float[Array, "n k"], ...]


class Kind(enum.IntEnum):
    """What a particle is. Stored per particle in `State.kind` (int32).

    The integer values are part of the run-file format (docs/architecture.md).
    """

    FLUID = 0
    WALL = 1  # fixed, pressure solved (Dirichlet/PPE row), the "pressure wall" layer
    DUMMY = 2  # fixed, no pressure: only completes the number density near walls
    RIGID = 3
    ELASTIC = 4
    SEDIMENT = 5


# Kinds whose pressure is solved (a PPE row) and that push on neighbours.
PRESSURE_KINDS = (Kind.FLUID, Kind.WALL, Kind.RIGID, Kind.ELASTIC)
# Kinds advanced by the fluid equations (bodies are "solved as fluid", then projected).
MOBILE_KINDS = (Kind.FLUID, Kind.RIGID, Kind.ELASTIC)


def is_kind(kind, kinds) -> "Bool[Array, ' n']":
    """Whether each entry of the int array `kind` is one of `kinds` (static tuple)."""
    import jax.numpy as jnp

    out = kind == int(kinds[0])
    for k in kinds[1:]:
        out = jnp.logical_or(out, kind == int(k))
    return out
