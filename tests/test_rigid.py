"""Rigid bodies: rotations, the momentum-conserving projection, free-body
conservation, vmap over body density, the body scenes, a bit-exact restart, and
the failure paths of `add_rigid_bodies`."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import geometry
from jaxmps.bodies import rotation as rot


def test_quaternion_rotation_sanity(rng):
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    r = np.asarray(rot.matrix(jnp.asarray(q), 3))
    eye = np.broadcast_to(np.eye(3), r.shape)
    np.testing.assert_allclose(np.swapaxes(r, 1, 2) @ r, eye, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    # Hamilton product: i j = k, and the scalar part has the minus sign.
    i, j = jnp.array([0.0, 1, 0, 0]), jnp.array([0.0, 0, 1, 0])
    np.testing.assert_allclose(rot.quaternion_multiply(i, j), [0, 0, 0, 1])
    np.testing.assert_allclose(rot.quaternion_multiply(i, i), [-1, 0, 0, 0])
    # Composing increments of a constant spin gives the exact angle omega t.
    omega = np.array([0.3, -0.2, 0.9])
    dt, steps = 1e-2, 700
    orientation = rot.identity(3, 1, jnp.float64)
    for _ in range(steps):
        orientation = rot.rotate(orientation, jnp.asarray(omega * dt)[None], 3)
    expected = rot.quaternion_from_rotation_vector(jnp.asarray(omega * dt * steps))
    overlap = np.sum(np.asarray(orientation[0]) * np.asarray(expected))
    np.testing.assert_allclose(np.abs(overlap), 1.0, atol=1e-12)
    # Finite gradient through the identity rotation.
    g = jax.grad(lambda t: rot.quaternion_from_rotation_vector(t)[1])(jnp.zeros(3))
    np.testing.assert_allclose(g, [0.5, 0, 0])


def _free_body(dim, spin, viscosity=1e-3, **mass_properties):
    l0 = 0.1
    upper = [0.5, 0.3] if dim == 2 else [0.5, 0.3, 0.2]
    box = geometry.block([0.0] * dim, upper, l0)
    # Rotation changes how cells fill; a capacity of all particles always fits.
    scene = jaxmps.make_scene(
        box, l0, ([-3.0] * dim, [3.0] * dim), candidate_capacity=len(box)
    )
    params = jaxmps.make_params(dim, dt=1e-3, gravity=0.0, viscosity=viscosity)
    centre = box.mean(axis=0)
    velocity = np.zeros_like(box)
    velocity[:, 0] = 0.3
    if dim == 2:
        arm = box - centre
        velocity += spin * np.stack([-arm[:, 1], arm[:, 0]], axis=1)
    else:
        velocity += np.cross(np.asarray(spin), box - centre)
    state = jaxmps.make_state(scene, box, np.zeros(len(box), int), velocity=velocity)
    return jaxmps.add_rigid_bodies(
        scene, params, state, np.zeros(len(box), int), density=500.0, **mass_properties
    )


def _at_rest(state):
    """`state` with its particles and bodies at rest."""
    return eqx.tree_at(
        lambda s: (s.velocity, s.rigid.velocity, s.rigid.angular_velocity),
        state,
        (
            state.velocity * 0,
            state.rigid.velocity * 0,
            state.rigid.angular_velocity * 0,
        ),
    )


def _momenta(state, density, l0, dim):
    m = density * l0**dim
    arm = np.asarray(state.position) - np.asarray(state.rigid.centre[0])
    v = np.asarray(state.velocity)
    linear = m * v.sum(axis=0)
    if dim == 2:
        angular = m * np.sum(arm[:, 0] * v[:, 1] - arm[:, 1] * v[:, 0])
    else:
        angular = m * np.cross(arm, v).sum(axis=0)
    return linear, np.atleast_1d(angular)


@pytest.mark.parametrize("dim,spin", [(2, 2.0), (3, (1.0, 0.5, 2.0))])
def test_free_body_conserves_momentum_and_shape(dim, spin):
    """A spinning body in free flight (viscosity on, no gravity): linear and angular
    momentum (about the moving centre) are kept to round-off, also in 3-D where the
    angular velocity precesses, and the particle distances never change."""
    scene, params, state = _free_body(dim, spin)
    out = jaxmps.simulate(scene, params, state, n_steps=600, save_every=600)
    assert out.result == jaxmps.Result.successful
    p0, l0_ = _momenta(state, 500.0, 0.1, dim)
    p1, l1 = _momenta(out.state, 500.0, 0.1, dim)
    np.testing.assert_allclose(p1, p0, rtol=1e-11, atol=1e-11 * np.abs(p0).max())
    np.testing.assert_allclose(l1, l0_, rtol=1e-11, atol=1e-11 * np.abs(l0_).max())
    x0, x1 = np.asarray(state.position), np.asarray(out.state.position)
    d0 = np.linalg.norm(x0[:, None] - x0[None], axis=-1)
    d1 = np.linalg.norm(x1[:, None] - x1[None], axis=-1)
    np.testing.assert_allclose(d1, d0, atol=1e-12)
    if dim == 3:  # an asymmetric body's angular velocity does change
        w0 = np.asarray(state.rigid.angular_velocity[0])
        w1 = np.asarray(out.state.rigid.angular_velocity[0])
        assert np.linalg.norm(w1 - w0) > 0.1


@pytest.mark.parametrize("dim", [2, 3])
def test_projection_keeps_momentum_of_tentative_velocities(dim, rng):
    """Digest test 12: whatever the tentative velocities, the projected body carries
    their linear momentum and their angular momentum about the step-k centre."""
    scene, params, state = _free_body(dim, 0.0 if dim == 2 else (0.0, 0.0, 0.0))
    u_hat = jnp.asarray(rng.normal(size=state.velocity.shape))
    tentative = eqx.tree_at(lambda s: s.velocity, state, u_hat)
    nbrs = jaxmps.neighbours.build(
        scene.grid, state.position, state.active, scene.max_neighbours, scene.r_e
    )
    pairs = jaxmps.operators.make_pairs(
        nbrs.index, state.position, scene.weight, scene.r_e
    )
    zero = jnp.zeros_like(state.velocity)
    load = jaxmps.FluidLoad(pairs=pairs, gradient=zero, wall_gradient=zero)
    moved = scene.rigid.advance(scene.discretisation, params, tentative, load)
    m = 500.0 * 0.1**dim
    arm_k = np.asarray(state.position) - np.asarray(state.rigid.centre[0])
    p_hat = m * np.asarray(u_hat).sum(axis=0)
    l_hat = m * np.asarray(rot.cross(jnp.asarray(arm_k), u_hat)).sum(axis=0)
    p_new = m * np.asarray(moved.velocity).sum(axis=0)
    np.testing.assert_allclose(p_new, p_hat, rtol=1e-12, atol=1e-12)
    # Angular momentum of the new particle velocities about the new centre.
    arm = np.asarray(moved.position) - np.asarray(moved.rigid.centre[0])
    l_new = m * np.asarray(rot.cross(jnp.asarray(arm), moved.velocity)).sum(axis=0)
    np.testing.assert_allclose(l_new, l_hat, rtol=1e-10, atol=1e-12)
    # Centre displacement = mean tentative displacement (eq. 2.5-4).
    np.testing.assert_allclose(
        moved.rigid.centre[0] - state.rigid.centre[0],
        float(params.dt) * np.asarray(u_hat).mean(axis=0),
        atol=1e-14,
    )


@pytest.mark.parametrize("dim", [2, pytest.param(3, marks=pytest.mark.slow)])
def test_body_with_given_centre_of_mass_and_gyration_moves_about_it(dim):
    """A body whose centre of mass G is off its particles' centroid, with given
    radii of gyration, in free flight (no gravity): G moves in a straight line at
    constant speed, the centroid turns about G, the angular momentum about G is
    I_G omega with I_G = M k^2, kept (in 2-D omega itself is constant, so the turn
    is omega t). Under gravity alone it falls without turning (gravity acts at G)."""
    offset = [0.08, -0.05] if dim == 2 else [0.08, -0.05, 0.03]
    radii = [0.3] if dim == 2 else [0.2, 0.25, 0.3]
    spin = 2.0 if dim == 2 else (1.0, 0.5, 2.0)
    scene, params, state = _free_body(dim, spin, centre_of_mass=offset, gyration=radii)
    mass = 500.0 * 0.1**dim * state.rigid.reference.shape[0]
    steps, dt = 600, float(params.dt)
    out = jaxmps.simulate(scene, params, state, n_steps=steps, save_every=steps)
    assert out.result == jaxmps.Result.successful

    def centre_of_mass(rs):
        r = np.asarray(rot.matrix(rs.orientation, dim))[0]
        return np.asarray(rs.centre[0]) + r @ np.asarray(offset)

    def momentum(rs):
        r = np.asarray(rot.matrix(rs.orientation, dim))[0]
        if dim == 2:
            return mass * radii[0] ** 2 * np.asarray(rs.angular_velocity[0])
        inertia = r @ np.diag(mass * np.square(radii)) @ r.T
        return inertia @ np.asarray(rs.angular_velocity[0])

    g0, g1 = centre_of_mass(state.rigid), centre_of_mass(out.state.rigid)
    r0 = np.asarray(rot.matrix(state.rigid.orientation, dim))[0]
    w0 = np.asarray(state.rigid.angular_velocity[0])
    velocity_g = np.asarray(state.rigid.velocity[0]) + np.asarray(
        rot.spin_cross(jnp.asarray(w0), jnp.asarray(r0 @ np.asarray(offset)))
    )
    np.testing.assert_allclose(g1, g0 + steps * dt * velocity_g, atol=1e-11)
    np.testing.assert_allclose(
        momentum(out.state.rigid), momentum(state.rigid), rtol=1e-11, atol=1e-13
    )
    # The centroid is off G by the rotated offset, and did move round it.
    centroid_arm = np.asarray(out.state.rigid.centre[0]) - g1
    np.testing.assert_allclose(
        np.linalg.norm(centroid_arm), np.linalg.norm(offset), rtol=1e-12
    )
    if dim == 2:
        angle = float(out.state.rigid.orientation[0, 0])
        np.testing.assert_allclose(angle, spin * steps * dt, rtol=1e-12)
    # Particles move rigidly with G's velocity plus omega x (r - G).
    w1 = np.asarray(out.state.rigid.angular_velocity[0])
    expected = velocity_g + np.asarray(
        rot.spin_cross(
            jnp.asarray(w1)[None], jnp.asarray(np.asarray(out.state.position) - g1)
        )
    )
    np.testing.assert_allclose(out.state.velocity, expected, atol=1e-11)

    falling = _at_rest(state)
    down = dataclasses.replace(params, gravity=jnp.asarray([0.0] * (dim - 1) + [-9.81]))
    fell = jaxmps.simulate(scene, down, falling, n_steps=100, save_every=100).state
    # (gravity acting at the centroid would spin it up to about 0.9 rad/s)
    np.testing.assert_allclose(fell.rigid.angular_velocity, 0.0, atol=1e-12)
    t = 100 * dt
    np.testing.assert_allclose(
        centre_of_mass(fell.rigid)[-1] - g0[-1], -9.81 * t * (t + dt) / 2, rtol=1e-12
    )


def test_projection_with_given_mass_properties():
    """The projection of tentative velocities u^ for a body with a given centre of
    mass G and gyration k: the momentum M V_G = m sum u^ and the angular momentum
    about G, m sum (r_i - G) x u^_i = M k^2 omega (a body at rest, no gravity)."""
    offset, radius = np.array([0.1, 0.04]), 0.25
    scene, params, state = _free_body(2, 0.0, centre_of_mass=offset, gyration=radius)
    state = _at_rest(state)
    rng = np.random.default_rng(4)
    u_hat = jnp.asarray(rng.normal(size=state.velocity.shape))
    tentative = eqx.tree_at(lambda s: s.velocity, state, u_hat)
    zero = jnp.zeros_like(state.velocity)
    nbrs = jaxmps.neighbours.build(
        scene.grid, state.position, state.active, scene.max_neighbours, scene.r_e
    )
    pairs = jaxmps.operators.make_pairs(
        nbrs.index, state.position, scene.weight, scene.r_e
    )
    load = jaxmps.FluidLoad(pairs=pairs, gradient=zero, wall_gradient=zero)
    moved = scene.rigid.advance(scene.discretisation, params, tentative, load)
    m, n = 500.0 * 0.1**2, state.position.shape[0]
    g = np.asarray(state.rigid.centre[0]) + offset
    arm = np.asarray(state.position) - g
    l_hat = m * np.asarray(rot.cross(jnp.asarray(arm), u_hat)).sum(axis=0)
    omega = float(moved.rigid.angular_velocity[0, 0])
    np.testing.assert_allclose(omega, l_hat[0] / (m * n * radius**2), rtol=1e-12)
    angle = float(moved.rigid.orientation[0, 0])
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    g_new = np.asarray(moved.rigid.centre[0]) + turn @ offset
    mean_u = np.asarray(u_hat).mean(axis=0)
    np.testing.assert_allclose(g_new - g, float(params.dt) * mean_u, atol=1e-14)
    p_new = m * np.asarray(moved.velocity).sum(axis=0)
    # Particles' momentum: M times the centroid's velocity, V_G + omega x (c - G).
    v_centroid = mean_u + omega * np.array([(turn @ offset)[1], -(turn @ offset)[0]])
    np.testing.assert_allclose(p_new, m * n * v_centroid, rtol=1e-12, atol=1e-12)


def test_rigid_params_vmap_matches_loop():
    """Body density is a Params field: vmapping it equals running each value."""
    scene, params, state = _free_body(2, 1.0)
    state = eqx.tree_at(lambda s: s.velocity, state, state.velocity * 0)
    params = dataclasses.replace(params, gravity=jnp.asarray([0.0, -9.81]))
    dens = jnp.asarray([[300.0], [900.0]])

    def run(d):
        p = eqx.tree_at(lambda p: p.rigid.density, params, d)
        return jaxmps.simulate(scene, p, state, 20, 20).state.rigid.centre

    batched = jax.vmap(run)(dens)
    for k in range(2):
        np.testing.assert_array_equal(batched[k], run(dens[k]))


def test_add_rigid_bodies_rejects_bad_input():
    l0 = 0.1
    box = geometry.block([0.0, 0.0], [0.3, 0.3], l0)
    walls, wk = geometry.tank([-1.0, -1.0], [1.0, 1.0], l0)
    pos = np.concatenate([box, walls])
    kind = np.concatenate([np.zeros(len(box), int), wk])
    scene = jaxmps.make_scene(pos, l0, ([-2, -2], [2, 2]), capacity=len(pos) + 5)
    params = jaxmps.make_params(2, dt=1e-3)
    state = jaxmps.make_state(scene, pos, kind)
    ids = np.r_[np.zeros(len(box), int), -np.ones(len(walls), int)]
    add = jaxmps.add_rigid_bodies
    with pytest.raises(ValueError, match="every body present"):
        add(scene, params, state, np.where(ids == 0, 1, -1), density=500.0)
    with pytest.raises(ValueError, match="particle"):
        single = ids.copy()
        single[0] = 1
        single[1:] = np.where(ids[1:] == 0, 0, -1)
        add(scene, params, state, single, density=500.0)
    with pytest.raises(ValueError, match="inactive"):
        add(scene, params, state, np.r_[ids, 0, 0], density=500.0)
    with pytest.raises(ValueError, match="all entries are -1"):
        add(scene, params, state, -np.ones(len(pos), int), density=500.0)
    # A body on top of the wall particles.
    over = geometry.block([-1.1, 0.0], [-0.8, 0.3], l0)
    pos2 = np.concatenate([over, walls])
    state2 = jaxmps.make_state(scene, pos2, kind)
    with pytest.raises(ValueError, match="overlaps"):
        add(scene, params, state2, ids, density=500.0)
    with pytest.raises(ValueError, match="positive"):
        add(scene, params, state, ids, density=-1.0)
    with pytest.raises(ValueError, match="gyration must be positive"):
        add(scene, params, state, ids, density=500.0, gyration=0.0)
    with pytest.raises(ValueError, match="centre_of_mass must be 2 value"):
        add(scene, params, state, ids, density=500.0, centre_of_mass=[0.1, 0, 0])
    with pytest.raises(ValueError, match="centre_of_mass must be finite"):
        add(scene, params, state, ids, density=500.0, centre_of_mass=[np.nan, 0])
    with pytest.raises(ValueError, match="friction_sweeps"):
        add(scene, params, state, ids, density=500.0, friction_sweeps=0)
    # Scene, Params and State must agree.
    s, p, st = add(scene, params, state, ids, density=500.0)
    with pytest.raises(ValueError, match="all be set or all be None"):
        jaxmps.step(s, params, st)
    with pytest.raises(
        ValueError, match=r"Params.rigid.density has shape \(2,\).*1 rigid bodies"
    ):
        bad = eqx.tree_at(lambda q: q.rigid.density, p, jnp.ones(2))
        jaxmps.step(s, bad, st)
    with pytest.raises(ValueError, match=r"Params.rigid.gyration has shape \(1, 3\)"):
        bad = dataclasses.replace(
            p, rigid=dataclasses.replace(p.rigid, gyration=jnp.ones((1, 3)))
        )
        jaxmps.step(s, bad, st)


def test_body_scenes_build_and_list():
    """Every body scene is listed, builds, and takes a few steps; a scene may change
    a common default (block_impact has no gravity); unknown parameters are refused."""
    names = jaxmps.scenes.available()
    for name in (
        "floating_box",
        "friction_tilt",
        "block_impact",
        "dam_break_box",
        "block_stack",
    ):
        assert name in names
    assert names["block_impact"]["gravity"] == 0.0
    case = jaxmps.scenes.build("dam_break_box", spacing=0.0146)
    assert int(case.scene.rigid.count) == 1
    out = jaxmps.simulate(case.scene, case.params, case.state, 10, 10)
    assert out.result == jaxmps.Result.successful
    with pytest.raises(ValueError, match="Unknown parameter"):
        jaxmps.scenes.build("floating_box", box_widht=0.1)
    with pytest.raises(ValueError, match="density_ratio"):
        jaxmps.scenes.floating_box(density_ratio=-1.0)
    with pytest.raises(ValueError, match="centre_of_gravity must lie inside the box"):
        jaxmps.scenes.floating_box(centre_of_gravity=0.3)
    with pytest.raises(ValueError, match="gyration must be"):
        jaxmps.scenes.floating_box(gyration=-0.1)
    with pytest.raises(ValueError, match="layout='pile'.*stack, row"):
        jaxmps.scenes.block_stack(layout="pile")
    with pytest.raises(ValueError, match="raise floor_length"):
        jaxmps.scenes.block_stack(layout="row", blocks=8, floor_length=2.0)
    with pytest.raises(ValueError, match="must cover the blocks"):
        jaxmps.scenes.block_stack(water_depth=0.5)
    with pytest.raises(ValueError, match="raise water_depth or lower angle"):
        jaxmps.scenes.friction_tilt(water_depth=1.0, angle=50.0)
    with pytest.raises(ValueError, match="friction_normal"):
        jaxmps.scenes.friction_tilt(friction_normal="weight")
    with pytest.raises(ValueError, match="friction_normal"):
        jaxmps.scenes.block_stack(friction_normal="weight")
    with pytest.raises(ValueError, match="blocks"):
        jaxmps.scenes.block_stack(blocks=0)
    for sweeps in (0, 2.5):
        with pytest.raises(ValueError, match="friction_sweeps"):
            jaxmps.scenes.block_stack(friction_sweeps=sweeps)


def test_restart_with_bodies_is_bit_exact(tmp_path):
    """A run with a body continued from its file equals the uninterrupted run bit for
    bit (particles and body state), and the file keeps the /bodies frames."""
    short = jaxmps.scenes.block_impact(spacing=0.25, t_end=0.05)
    long = jaxmps.scenes.block_impact(spacing=0.25, t_end=0.1)
    path = tmp_path / "impact.h5"
    jaxmps.run(short, out=path, save_every=0.01, progress=False)
    restarted = jaxmps.run(
        long, out=path, restart=True, save_every=0.01, progress=False
    )
    whole = jaxmps.run(long, out=tmp_path / "whole.h5", save_every=0.01, progress=False)
    for a, b in zip(jax.tree.leaves(restarted.state), jax.tree.leaves(whole.state)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    data = jaxmps.io.read_run(path)
    assert data.bodies["centre"].shape[0] == data.frames["time"].shape[0] == 11


def test_tilted_water_over_bodies_of_any_height_builds():
    """The tank over tilted water stands a fifth of the bodies' height above the
    surface, rounded up to whole spacings: a stack 1.2 m high at l0 = 0.05 m made
    it 0.24 m, and the scene was refused as "not a whole number of spacings"."""
    case = jaxmps.scenes.block_stack(
        block_size=0.3,
        block_height=0.6,
        base_width=1.0,
        floor_length=1.5,
        water_depth=1.5,
        angle=20.0,
    )
    walls = np.asarray(case.state.position)[np.asarray(case.state.kind) != 0]
    assert walls[:, 1].max() > 1.5 + 0.2 * 1.2
    case = jaxmps.scenes.friction_tilt(
        block_size=0.3, block_height=0.6, water_depth=1.0, angle=10.0, settle=0
    )
    assert int(np.asarray(case.state.active).sum()) > 0
