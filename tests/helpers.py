"""Test helpers: brute-force references and small scenes."""

import numpy as np

import jaxmps
from jaxmps.geometry import block, tank


def brute_force_neighbours(x, active, radius):
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    ref = (d < radius) & ~np.eye(len(x), dtype=bool)
    return ref & active[:, None] & active[None]


def listed(index, n):
    out = np.zeros((index.shape[0], n), dtype=bool)
    for i, row in enumerate(np.asarray(index)):
        for j in row:
            if j < n:
                out[i, j] = True
    return out


def small_tank(width=0.1, depth=0.1, l0=0.01, **scene_kw):
    """A 2-D water block in an open tank: (scene, params, state)."""
    fluid = block([0, 0], [width, depth], l0)
    walls, wk = tank([0, 0], [width, depth + 3 * l0], l0)
    pos = np.concatenate([fluid, walls])
    kind = np.concatenate([np.zeros(len(fluid), np.int32), wk])
    lower = np.array([-5 * l0, -5 * l0])
    upper = np.array([width + 5 * l0, depth + 10 * l0])
    scene = jaxmps.make_scene(pos, l0, (lower, upper), **scene_kw)
    params = jaxmps.make_params(2, dt=1e-3)
    state = jaxmps.make_state(scene, pos, kind)
    return scene, params, state
