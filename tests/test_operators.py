"""MPS operators on lattices and irregular clouds: n0 and lambda, weights at zero
and on padded slots, exact gradients of linear fields, the Laplacian of |r|^2, and
the small-matrix and pair-sum helpers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import lattice_pairs

import jaxmps
from jaxmps.neighbours import build
from jaxmps.operators import (
    CorrectedGradient,
    MPSWeight,
    StandardGradient,
    laplacian,
    make_pairs,
    number_density,
    reference_constants,
)


@pytest.mark.parametrize(
    "dim, n0, lam", [(2, 6.539697, 1.388351), (3, 14.418575, 1.701738)]
)
def test_reference_constants(dim, n0, lam):
    got_n0, got_lam = reference_constants(MPSWeight(), dim, 2.1)
    assert got_n0 == pytest.approx(n0, rel=1e-6)
    assert got_lam == pytest.approx(lam, rel=1e-6)


def test_weight_finite_value_and_gradient_at_zero_and_padding():
    w = MPSWeight()
    r = jnp.array([0.0, 1e-30, 0.5, 2.1, 3.0])
    valid = jnp.array([False, False, True, True, True])
    out = w(r, valid, 2.1)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, [0, 0, 2.1 / 0.5 - 1, 0, 0])
    g = jax.grad(lambda r: w(r, valid, 2.1).sum())(r)
    assert np.all(np.isfinite(g))
    # Through positions: coincident particles and padded slots give finite gradients.
    x = jnp.array([[0.0, 0.0], [0.0, 0.0], [0.5, 0.0]])
    index = jnp.array([[1, 2, 3], [0, 2, 3], [0, 1, 3]])
    g = jax.grad(lambda x: make_pairs(index, x, w, 2.1).weight.sum())(x)
    assert np.all(np.isfinite(g))


def _lattice(dim, l0=1.0, size=9, jitter=0.0, rng=None):
    return lattice_pairs(dim, l0, size, jitter, rng)


@pytest.mark.parametrize("dim", [2, 3])
def test_number_density_interior_equals_n0(dim):
    scene, x, pairs, interior = _lattice(dim, size=9 if dim == 2 else 8)
    n = np.asarray(number_density(pairs))
    np.testing.assert_allclose(n[interior], scene.n0, rtol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_gradients_exact_on_linear_field_on_lattice(dim):
    scene, x, pairs, interior = _lattice(dim, size=9 if dim == 2 else 8)
    a = np.arange(1, dim + 1) * 0.7
    phi = jnp.asarray(x @ a + 3.0)
    include = pairs.valid
    for grad in (StandardGradient(), CorrectedGradient()):
        g = np.asarray(grad(pairs, phi, scene.discretisation, include))
        np.testing.assert_allclose(
            g[interior], np.tile(a, (interior.sum(), 1)), rtol=1e-10
        )


def test_corrected_gradient_exact_on_irregular_cloud(rng):
    scene, x, pairs, interior = _lattice(2, size=10, jitter=0.2, rng=rng)
    a = np.array([1.3, -0.4])
    phi = jnp.asarray(x @ a)
    g = np.asarray(CorrectedGradient()(pairs, phi, scene.discretisation, pairs.valid))
    np.testing.assert_allclose(g[interior], np.tile(a, (interior.sum(), 1)), rtol=1e-10)
    # The standard gradient is not exact there (so the test above can fail).
    s = np.asarray(StandardGradient()(pairs, phi, scene.discretisation, pairs.valid))
    assert np.abs(s[interior] - a).max() > 1e-3


@pytest.mark.parametrize("dim", [2, 3])
def test_laplacian_of_r_squared_on_lattice(dim):
    l0 = 0.01
    scene, x, pairs, interior = _lattice(dim, size=9 if dim == 2 else 8)
    # rescale to l0 = 0.01 to check the units of lambda
    scene2 = jaxmps.make_scene(
        x * l0, l0, (np.full(dim, -3 * l0), np.full(dim, 12 * l0))
    )
    nbrs = build(
        scene2.grid,
        jnp.asarray(x * l0),
        jnp.ones(len(x), bool),
        scene2.max_neighbours,
        scene2.r_e,
    )
    p2 = make_pairs(nbrs.index, jnp.asarray(x * l0), scene2.weight, scene2.r_e)
    phi = jnp.asarray(np.sum((x * l0) ** 2, axis=1))
    lap = np.asarray(laplacian(p2, phi, scene2.n0, scene2.lam, dim))
    np.testing.assert_allclose(lap[interior], 2.0 * dim, rtol=1e-10)
    del pairs, scene


@pytest.mark.parametrize("d", [1, 2, 3])
def test_small_matrix_helpers_match_linalg(d, rng):
    """The written-out determinant and adjugate inverse used by the corrected
    gradient agree with LAPACK's on random and near-singular blocks, and so does
    their gradient (central differences through jnp.linalg.inv)."""
    from jaxmps._numerics import small_determinant, small_inverse

    m = rng.normal(size=(40, d, d))
    m[0] = np.eye(d) * 1e-6 + 1e-7 * rng.normal(size=(d, d))
    m = jnp.asarray(m)
    det = small_determinant(m)
    np.testing.assert_allclose(det, jnp.linalg.det(m), rtol=1e-10, atol=1e-30)
    np.testing.assert_allclose(
        small_inverse(m[1:], det[1:]), jnp.linalg.inv(m[1:]), rtol=1e-9, atol=1e-12
    )

    def f(x, inverse):
        return jnp.sum(jnp.sin(inverse(x)))

    g = jax.grad(f)(m[1:], lambda x: small_inverse(x, small_determinant(x)))
    g_ref = jax.grad(f)(m[1:], jnp.linalg.inv)
    np.testing.assert_allclose(g, g_ref, rtol=1e-8, atol=1e-10)


def test_pair_sums_match_axis_reductions(rng):
    from jaxmps._numerics import (
        component_dot,
        last_axis_dot,
        pair_differences,
        pair_sum,
        take_rows,
    )

    c = jnp.asarray(rng.normal(size=(7, 5)))
    v = jnp.asarray(rng.normal(size=(3, 7, 5)))
    u = jnp.asarray(rng.normal(size=(3, 7, 5)))
    np.testing.assert_allclose(pair_sum(c, tuple(v)), jnp.einsum("nk,dnk->nd", c, v))
    np.testing.assert_allclose(component_dot(tuple(u), tuple(v)), jnp.sum(u * v, 0))
    np.testing.assert_allclose(
        last_axis_dot(u.T, v.T), jnp.sum(u.T * v.T, axis=-1), rtol=1e-12
    )
    field = jnp.asarray(rng.normal(size=(7, 3)))
    index = jnp.asarray(rng.integers(0, 8, size=(7, 5)))  # 7 is the sentinel
    expected = take_rows(field, index) - field[:, None, :]
    np.testing.assert_allclose(
        jnp.stack(pair_differences(field, index)), jnp.moveaxis(expected, -1, 0)
    )


def test_materialised_is_the_identity_under_jit_grad_and_vmap(rng):
    """The copy that keeps XLA from recomputing a gathered field per element
    changes nothing: values, reverse and forward derivatives, a batch."""
    from jaxmps._numerics import materialised, take_rows

    x = jnp.asarray(rng.normal(size=(6, 2)))
    index = jnp.asarray(rng.integers(0, 7, size=(6, 4)))

    def f(x):
        return jnp.sum(jnp.sin(take_rows(materialised(jnp.exp(x)), index)) ** 2)

    def g(x):
        return jnp.sum(jnp.sin(take_rows(jnp.exp(x), index)) ** 2)

    np.testing.assert_array_equal(jax.jit(materialised)(x), x)
    np.testing.assert_allclose(jax.jit(f)(x), g(x), rtol=1e-14)
    np.testing.assert_allclose(jax.grad(f)(x), jax.grad(g)(x), rtol=1e-13)
    t = jnp.ones_like(x)
    np.testing.assert_allclose(
        jax.jvp(f, (x,), (t,))[1], jax.jvp(g, (x,), (t,))[1], rtol=1e-13
    )
    batch = jnp.stack([x, 2 * x])
    np.testing.assert_array_equal(jax.vmap(materialised)(batch), batch)
