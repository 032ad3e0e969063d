"""Free-surface detection (seed 000 §2.4.1): the beta rule n* < beta n0 and the
isolated-surface filter, on a water block whose surface is known."""

import jax.numpy as jnp
import numpy as np
from helpers import small_tank

from jaxmps import Kind, neighbours
from jaxmps.fluid import FreeSurface, detect_surface
from jaxmps.operators import make_pairs, number_density


def _tank():
    scene, params, state = small_tank(width=0.1, depth=0.1, l0=0.01)
    nbrs = neighbours.build(
        scene.grid, state.position, state.active, scene.max_neighbours, scene.r_e
    )
    pairs = make_pairs(nbrs.index, state.position, scene.weight, scene.r_e)
    return scene, params, state, pairs, number_density(pairs)


def test_beta_rule_flags_the_top_of_a_still_block_and_nothing_inside():
    """On the initial lattice the top fluid row has n < 0.97 n0 and every interior
    fluid particle n = n0 (next to walls the wall and dummy layers complete it)."""
    scene, params, state, pairs, n = _tank()
    surface = np.asarray(
        detect_surface(
            FreeSurface(), params.beta, scene.n0, n, state.kind, state.active, pairs
        )
    )
    x = np.asarray(state.position)
    fluid = np.asarray(state.kind) == int(Kind.FLUID)
    top = fluid & (x[:, 1] > x[fluid, 1].max() - 0.5 * scene.spacing)
    assert surface[top].all()
    below = fluid & (x[:, 1] < x[fluid, 1].max() - 2.5 * scene.spacing)
    assert not surface[below].any()
    # Dummies carry no pressure: never flagged.
    assert not surface[np.asarray(state.kind) == int(Kind.DUMMY)].any()


def test_isolated_filter_unflags_a_lone_low_density_particle():
    """An interior particle whose number density dips below beta n0 (a neighbour
    moved away) has many neighbours and no flagged ones: the filter keeps it in the
    pressure solve; without the filter (N = -1) the beta rule flags it."""
    scene, params, state, pairs, n = _tank()
    x = np.asarray(state.position)
    fluid = np.asarray(state.kind) == int(Kind.FLUID)
    centre = np.array([0.05, 0.045])
    i = int(np.argmin(np.where(fluid, np.linalg.norm(x - centre, axis=1), np.inf)))
    dipped = n.at[i].set(0.9 * scene.n0)
    args = (params.beta, scene.n0, dipped, state.kind, state.active, pairs)
    assert not bool(detect_surface(FreeSurface(), *args)[i])
    assert bool(detect_surface(FreeSurface(max_surface_neighbours=-1), *args)[i])


def test_inactive_slots_are_never_surface():
    scene, params, state, pairs, n = _tank()
    active = state.active.at[:5].set(False)
    surface = detect_surface(
        FreeSurface(),
        params.beta,
        scene.n0,
        jnp.zeros_like(n),
        state.kind,
        active,
        pairs,
    )
    assert not bool(jnp.any(surface[:5]))
