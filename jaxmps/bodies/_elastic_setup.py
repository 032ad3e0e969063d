"""Host-side construction of the elastic bodies' sub-state (NumPy; validates)."""

import itertools

import jax.numpy as jnp
import numpy as np

from .._state import ElasticState
from . import rotation as rot


def reference_neighbours(
    position: np.ndarray, body: np.ndarray, radius: float
) -> np.ndarray:
    """For each of the m points, the others of its body closer than `radius`, as
    point numbers in an (m, k) array padded with m (k the largest count; a cell
    list, so O(m))."""
    m, dim = position.shape
    cell = np.floor((position - position.min(axis=0)) / radius).astype(np.int64)
    extent = cell.max(axis=0) + 3
    cell += 1  # a margin of one empty cell each side

    def key(c):
        return np.ravel_multi_index(tuple(c.T), tuple(extent))

    own = key(cell)
    order = np.argsort(own, kind="stable")
    sorted_keys = own[order]
    pairs_i, pairs_j = [], []
    for offset in itertools.product((-1, 0, 1), repeat=dim):
        other = key(cell + np.asarray(offset))
        start = np.searchsorted(sorted_keys, other, side="left")
        stop = np.searchsorted(sorted_keys, other, side="right")
        for slot in range(int((stop - start).max(initial=0))):
            has = start + slot < stop
            i = np.nonzero(has)[0]
            j = order[start[has] + slot]
            d2 = np.sum((position[j] - position[i]) ** 2, axis=1)
            keep = (i != j) & (body[i] == body[j]) & (d2 < radius**2)
            pairs_i.append(i[keep])
            pairs_j.append(j[keep])
    i = np.concatenate(pairs_i)
    j = np.concatenate(pairs_j)
    order = np.lexsort((j, i))
    i, j = i[order], j[order]
    counts = np.bincount(i, minlength=m)
    k = max(int(counts.max(initial=0)), 1)
    out = np.full((m, k), m, np.int64)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    out[i, np.arange(i.size) - first[i]] = j
    return out


def elastic_state(
    position: np.ndarray,
    velocity: np.ndarray,
    ids: np.ndarray,
    clamped: np.ndarray,
    radius: float,
    dtype,
) -> ElasticState:
    """The sub-state of the elastic particles (slots with ids >= 0), unstrained at
    their given positions; refuses a particle with no neighbour of its own body
    (a body of one particle, or one apart from the rest)."""
    index = np.nonzero(ids >= 0)[0]
    body = ids[index]
    reference = position[index]
    neighbours = reference_neighbours(reference, body, radius)
    lonely = np.all(neighbours == index.size, axis=1)
    if np.any(lonely):
        first = int(index[np.argmax(lonely)])
        raise ValueError(
            f"{int(lonely.sum())} elastic particle(s) (the first in slot {first}, body "
            f"{int(ids[first])}) have no particle of their body within r_e: an elastic "
            "body needs its particles on one lattice (a body of one particle has no "
            "stress)."
        )
    dim = position.shape[1]
    held = clamped[index]
    return ElasticState(
        index=jnp.asarray(index, jnp.int32),
        body=jnp.asarray(body, jnp.int32),
        reference=jnp.asarray(reference, dtype),
        neighbours=jnp.asarray(neighbours, jnp.int32),
        clamped=jnp.asarray(held),
        position=jnp.asarray(reference, dtype),
        velocity=jnp.asarray(np.where(held[:, None], 0.0, velocity[index]), dtype),
        rotation=rot.identity(dim, index.size, dtype),
        angular_velocity=jnp.zeros((index.size, rot.spin_size(dim)), dtype),
        elastic_pressure=jnp.zeros((index.size,), dtype),
        contact_force=jnp.zeros((index.size, dim), dtype),
        wall_push=jnp.zeros((ids.size, dim), dtype),
    )
