"""Test helpers: brute-force references and small scenes."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

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


def scheme_of(solver=None, r_e=None, weight=None):
    """The standard scheme (the explicit one for an `Explicit` solver) with its
    solver, influence radius or weight replaced."""
    explicit = isinstance(solver, jaxmps.Explicit)
    scheme = (
        jaxmps.schemes.explicit(solver) if explicit else jaxmps.schemes.standard(solver)
    )
    changes = {"r_e": r_e, "weight": weight}
    return scheme.replace(**{k: v for k, v in changes.items() if v is not None})


def small_tank(width=0.1, depth=0.1, l0=0.01, solver=None, **scene_kw):
    """A 2-D water block in an open tank: (scene, params, state)."""
    fluid = block([0, 0], [width, depth], l0)
    walls, wk = tank([0, 0], [width, depth + 3 * l0], l0)
    pos = np.concatenate([fluid, walls])
    kind = np.concatenate([np.zeros(len(fluid), np.int32), wk])
    lower = np.array([-5 * l0, -5 * l0])
    upper = np.array([width + 5 * l0, depth + 10 * l0])
    scene = jaxmps.make_scene(
        pos, l0, (lower, upper), scheme=scheme_of(solver), **scene_kw
    )
    params = jaxmps.make_params(2, dt=1e-3)
    state = jaxmps.make_state(scene, pos, kind)
    return scene, params, state


def lattice_pairs(
    dim, l0=1.0, size=9, jitter=0.0, rng=None, r_e=None, weight=None, **scene_kw
):
    """A size^dim lattice (optionally jittered by +-jitter l0) and its pairs:
    (scene, x, pairs, interior), `interior` marking points at least 3 l0 from the
    edge (a full neighbourhood for r_e <= 3 l0)."""
    import jax
    import jax.numpy as jnp

    from jaxmps.neighbours import build
    from jaxmps.operators import make_pairs

    x = block([0.0] * dim, [size * l0] * dim, l0)
    if jitter:
        x = x + rng.uniform(-jitter, jitter, x.shape) * l0
    domain = (np.full(dim, -3 * l0), np.full(dim, (size + 3) * l0))
    scheme = scheme_of(r_e=r_e, weight=weight)
    scene = jaxmps.make_scene(x, l0, domain, scheme=scheme, **scene_kw)
    search = jax.jit(build, static_argnums=(0, 3, 4))
    nbrs = search(
        scene.grid,
        jnp.asarray(x),
        jnp.ones(len(x), bool),
        scene.max_neighbours,
        scene.r_e,
    )
    pairs = make_pairs(nbrs.index, jnp.asarray(x), scene.weight, scene.r_e)
    interior = np.all((x > 3 * l0) & (x < (size - 3) * l0), axis=1)
    return scene, x, pairs, interior


ROOT = Path(__file__).resolve().parents[1]


def python_with_devices(code: str, devices: int = 1, timeout: float = 300, env=None):
    """Run `code` in a fresh float64 interpreter with `devices` CPU devices
    (XLA_FLAGS must be set before JAX starts); its stdout."""
    environment = {
        **os.environ,
        "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices}",
        "JAX_PLATFORMS": "cpu",
        "JAX_ENABLE_X64": "1",
        "PYTHONPATH": str(ROOT),
        **(env or {}),
    }
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=environment,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout
