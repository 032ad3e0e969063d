"""Contact and friction of rigid bodies: the Coulomb law (stick/slip, normal-force
estimates, the smooth variant), the friction onset tan(theta) = mu (vmapped over
angles), the sliding acceleration and the gradients of the sliding distance with
respect to mu_k and gravity, two bodies colliding, and the impact impulse bounds."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import geometry


def test_friction_onset_at_tan_theta_equals_mu(tilt_sweep):
    """Stays put at tan(theta) = 0.95 mu, slides at 1.05 mu, for mu = 0.2 ... 0.8."""
    mu, ratio, dx, theory = tilt_sweep
    for m, r, d, t in zip(mu, ratio, dx, theory):
        if r < 1:
            assert abs(d) < 1e-3, f"mu={m}: moved {d:.2e} m below the onset"
        elif r < 1.5:
            assert d > 0.5 * t, f"mu={m}: slid {d:.3g} m, theory {t:.3g} m"


def test_sliding_acceleration(tilt_sweep):
    """At tan(theta) = 2 mu the distance is within 10 % of g(sin - mu cos) T^2 / 2."""
    mu, ratio, dx, theory = tilt_sweep
    fast = ratio == 2.0
    np.testing.assert_allclose(dx[fast], theory[fast], rtol=0.10)


@pytest.mark.parametrize(
    "torque",
    [
        pytest.param(False, id="no_torque", marks=pytest.mark.long),
        pytest.param(True, id="torque", marks=pytest.mark.slow),
    ],
)
def test_sliding_distance_gradients_match_differences_and_theory(torque):
    """The gradient of the sliding distance by reverse mode, w.r.t. mu_k and both
    components of gravity, equals central finite differences and the uniform
    sliding law x = (g_x - mu_k |g_y|) T^2 / 2; w.r.t. mu_s it is exactly zero
    while the block slides. With the friction torque too (the face's couple keeps
    the block upright)."""
    case = jaxmps.scenes.friction_tilt(mu_static=0.4, friction_torque=torque)
    theta = math.atan(0.8)
    params = eqx.tree_at(
        lambda p: p.gravity,
        case.params,
        jnp.asarray([G * math.sin(theta), -G * math.cos(theta)]),
    )
    params = eqx.tree_at(lambda p: p.rigid.mu_kinetic, params, 0.4 * jnp.ones(1))
    n = 100

    def distance(p):
        out = jaxmps.simulate(case.scene, p, case.state, n, n // 4, throw=False)
        return out.state.rigid.centre[0, 0]

    grad = jax.grad(distance)(params)
    assert float(jnp.abs(grad.rigid.mu_static).max()) == 0.0
    # A small step: the MPS weight has a kink at r_e, so pairs crossing it as the
    # block slides make the distance piecewise smooth; a step of 1e-4 can straddle a
    # kink (measured: 6 % off over 100 steps at tan(theta) = 0.6, mu = 0.45).
    h = 1e-6
    t = n * float(params.dt)
    mu_k = lambda m: eqx.tree_at(lambda p: p.rigid.mu_kinetic, params, m)  # noqa: E731
    fd_mu = (
        distance(mu_k(jnp.full(1, 0.4 + h))) - distance(mu_k(jnp.full(1, 0.4 - h)))
    ) / (2 * h)
    d_mu = float(grad.rigid.mu_kinetic[0])
    assert d_mu < 0
    np.testing.assert_allclose(d_mu, float(fd_mu), rtol=1e-4)
    np.testing.assert_allclose(d_mu, -G * math.cos(theta) * t * t / 2, rtol=0.1)
    # Gravity along (1, 1) / sqrt 2: d x / d g_x = T^2 / 2, d x / d g_y = mu_k T^2 / 2.
    g0, along = params.gravity, jnp.asarray([1.0, 1.0]) / math.sqrt(2)
    tilt = lambda g: eqx.tree_at(lambda p: p.gravity, params, g)  # noqa: E731
    fd = (distance(tilt(g0 + h * G * along)) - distance(tilt(g0 - h * G * along))) / (
        2 * h * G
    )
    d_g = float(jnp.vdot(grad.gravity, along))
    np.testing.assert_allclose(d_g, float(fd), rtol=1e-4)
    np.testing.assert_allclose(d_g, 1.4 * t * t / 2 / math.sqrt(2), rtol=0.1)


def test_block_impact_impulse_within_momentum_bounds():
    """Seed 000 §8.4: a 2.5 m block at 1 m/s onto a wall. The impulse per metre,
    both from the wall pressure and from the body's momentum change, lies between
    rho A v = 6.25 (plastic) and 2 rho A v = 12.5 kN s/m (elastic)."""
    case = jaxmps.scenes.block_impact(t_end=0.4)
    dt = float(case.params.dt)
    s = _run_probes(case, 0.4, saves=round(0.4 / dt))
    wall = np.sum(s["wall_force"]) * dt
    mass = case.config["density"] * case.config["block_size"] ** 2
    body = mass * (s["block_velocity_y"][-1] + 1.0)
    np.testing.assert_allclose(s["block_impulse_y"][-1], body, rtol=1e-9)
    for impulse in (wall, body):
        assert 6.25e3 * (1 - 1e-9) <= impulse <= 12.5e3, impulse
    assert s["block_y"].min() > 0.5 * case.config["block_size"] - 0.5 * 0.1


@pytest.mark.parametrize("angle", [0.0, 20.0])
def test_the_floor_under_a_resting_block_carries_its_weight(angle):
    """A dry block (1 x 2 m, on its end at 20 degrees) resting on the floor: the
    floor's `WallForce` (its pressure less the dry wall's, and the contact push
    the block exerts on it) is the block's weight along the floor normal,
    M g cos(theta), within 2 %. The push carries most of it (a dry block's
    bottom particles carry little pressure); summed over all walls its reaction
    is along the normal alone."""
    tall = dict(block_height=2.0, friction_torque=True) if angle else {}
    case = jaxmps.scenes.friction_tilt(angle=angle, t_end=0.1, **tall)
    c, l0 = case.config, case.config["spacing"]
    dry = case.scene.solver.surface_head * c["density"] * G * l0
    floor = jaxmps.scenes.WallForce(
        "floor", (-1.0, -0.6 * l0), (100.0, 0.1 * l0), l0, dry
    )
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=[0.05, 0.1],
        observe=jaxmps.scenes.observe_probes((floor,)),
    )
    assert out.result == jaxmps.Result.successful
    rigid = out.state.rigid
    mass = c["density"] * c["density_ratio"] * float(jnp.sum(rigid.body >= 0)) * l0**2
    weight = mass * G * math.cos(math.radians(angle))
    np.testing.assert_allclose(np.asarray(out.saved["floor"]), weight, rtol=0.02)
    push = np.asarray(jnp.sum(rigid.wall_push, axis=0))
    assert -push[1] > 0.5 * weight, push
    assert abs(push[0]) < 1e-6 * weight, push


G = 9.81


def _run_probes(case, t_end, saves=20):
    dt = float(case.params.dt)
    n = max(saves, round(t_end / dt) // saves * saves)
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        n_steps=n,
        save_every=n // saves,
        observe=jaxmps.scenes.observe_probes(case.probes),
    )
    assert out.result == jaxmps.Result.successful
    return {k: np.asarray(v) for k, v in out.saved.items()}


def test_coulomb_law_stick_slip_and_normal_force_estimates():
    """The friction law on hand-made contacts: stick removes the whole tangential
    velocity, slip removes mu_k N dt / M of it, the normal velocity is left alone;
    the three normal-force estimates give their formulas."""
    from jaxmps.bodies import ContactPressure, Coulomb, SubmergedWeight

    params = jaxmps.make_params(2, dt=0.01, density=1000.0)
    mass, volume = jnp.asarray([100.0]), jnp.asarray([0.05])
    one = jnp.ones(1)
    law = Coulomb()
    # N = 1000 N: capacity mu N dt / M = 0.5 * 1000 * 0.01 / 100 = 0.05 m/s.
    v_stick = jnp.asarray([[0.04, -0.3]])
    impulse, sliding = law(
        _contact(), v_stick, mass, volume, 0.5 * one, 0.5 * one, params, 0.1, 2
    )
    np.testing.assert_allclose(impulse, [[-4.0, 0.0]], atol=1e-12)
    assert not bool(sliding[0])
    v_slip = jnp.asarray([[0.2, -0.3]])
    impulse, sliding = law(
        _contact(), v_slip, mass, volume, 0.5 * one, 0.3 * one, params, 0.1, 2
    )
    np.testing.assert_allclose(impulse, [[-0.3 * 1000 * 0.01, 0.0]], atol=1e-12)
    assert bool(sliding[0])
    # Seed 000: N = sum P l0^(d-1) = 2000 * 0.1 = 200 N.
    seed0 = Coulomb(normal=ContactPressure())
    impulse, _ = seed0(
        _contact(), v_slip, mass, volume, 0.5 * one, 0.5 * one, params, 0.1, 2
    )
    np.testing.assert_allclose(impulse, [[-0.5 * 200 * 0.01, 0.0]], atol=1e-12)
    # Seed 002: N = (M - rho V) |g . n| = (100 - 50) * 9.81.
    seed2 = Coulomb(normal=SubmergedWeight())
    impulse, _ = seed2(
        _contact(), v_slip, mass, volume, 0.5 * one, 0.5 * one, params, 0.1, 2
    )
    np.testing.assert_allclose(impulse, [[-0.5 * 50 * 9.81 * 0.01, 0.0]], rtol=1e-12)


def test_smooth_coulomb_gives_a_gradient_while_sticking():
    """The exact law gives no gradient with respect to mu while the body sticks;
    `Coulomb(smoothing=...)` does, and tends to the exact law far from the switch."""
    from jaxmps.bodies import Coulomb

    params = jaxmps.make_params(2, dt=0.01)
    mass, volume = jnp.asarray([100.0]), jnp.asarray([0.05])
    v = jnp.asarray([[0.04, 0.0]])  # sticks: capacity 0.05 m/s at mu = 0.5

    def impulse_x(mu, law):
        m = mu * jnp.ones(1)
        return law(_contact(), v, mass, volume, m, m, params, 0.1, 2)[0][0, 0]

    assert float(jax.grad(impulse_x)(0.5, Coulomb())) == 0.0
    assert abs(float(jax.grad(impulse_x)(0.5, Coulomb(smoothing=0.01)))) > 1.0
    far = jnp.asarray([[1.0, 0.0]])  # slides fast: both remove 0.05 m/s
    exact = Coulomb()(
        _contact(),
        far,
        mass,
        volume,
        0.5 * jnp.ones(1),
        0.5 * jnp.ones(1),
        params,
        0.1,
        2,
    )[0]
    smooth = Coulomb(smoothing=1e-3)(
        _contact(),
        far,
        mass,
        volume,
        0.5 * jnp.ones(1),
        0.5 * jnp.ones(1),
        params,
        0.1,
        2,
    )[0]
    np.testing.assert_allclose(smooth, exact, rtol=1e-6)


@pytest.mark.slow
def test_two_bodies_collide_without_interpenetration():
    """Two free blocks of different densities meeting off-centre. Contact acts through
    the pressure pair forces (antisymmetric) and the collision guard:
    - total linear momentum is kept to round-off, with viscosity too (the viscous
      force on a body particle is scaled by rho0 / rho_body);
    - no particle of one body comes closer than 0.8 l0 to the other;
    - total angular momentum (orbital + spin, about the origin) changes by O(dt):
      the pair forces act along r_ij at the tentative positions while the projection
      takes lever arms at step k. Measured 0.16 % at dt = 1 ms, 0.09 % at 0.5 ms."""
    l0 = 0.1
    coarse = _two_blocks(1e-3, 1e-3)
    assert coarse["gap"].min() > 0.8 * l0
    assert np.abs(coarse["spin"][-1]).max() > 0.1  # the off-centre hit spun them
    # Each block carries 250 kg m/s (per metre) towards the other: the total is 0.
    np.testing.assert_allclose(coarse["linear"], 0.0, atol=1e-9)
    errors = []
    for dt in (1e-3, 5e-4):
        s = _two_blocks(0.0, dt)
        np.testing.assert_allclose(s["linear"], 0.0, atol=1e-9)
        errors.append(np.abs(s["angular"] - s["angular"][0]).max() / s["angular"][0])
    assert errors[0] < 3e-3
    assert errors[1] < 0.7 * errors[0]  # first order in dt


@pytest.mark.parametrize("dim", [2, 3])
def test_friction_between_free_bodies_keeps_momentum_and_dissipates(dim):
    """Two free blocks without gravity meeting face to face off-centre while
    sliding across each other (the second moves at -0.5 m/s towards the first
    and 0.4 m/s sideways): the total linear momentum is kept to round-off and
    the angular momentum about the origin to the collision's O(dt) (measured
    8e-5 without friction, 3e-4 to 4e-4 with). Without friction the contact
    exchanges no momentum along the face (each block's sideways momentum kept
    within 1 % of the second's; a contact that pushed along each particle's
    own normal moved the first block sideways at 0.04 m/s in 2-D, 0.13 in
    3-D), and the faces' couple turns the two together: they leave with the
    same angular velocity but the spin about the face's normal (within 5 %;
    measured 0.1 % in 2-D, 1.5 % in 3-D). With mu = 0.5 the blocks leave with
    less kinetic energy (measured 3 % in 2-D, 8 % in 3-D: 9 % and 10 % before
    the couple, which dissipates the relative turning with or without
    friction) and the sideways impulse between them is within mu times the
    normal one."""
    l0, dt = 0.1, 1e-3
    a = geometry.block([0.0] * dim, [0.5] * dim, l0)
    b = geometry.block([0.8] + [0.1] * (dim - 1), [1.3] + [0.6] * (dim - 1), l0)
    pos = np.concatenate([a, b])
    lo, hi = [-1.0] * dim, [2.0] + [1.5] * (dim - 1)
    scene = jaxmps.make_scene(pos, l0, (lo, hi), candidate_capacity=len(pos))
    params = jaxmps.make_params(dim, dt=dt, gravity=0.0)
    vel = np.zeros_like(pos)
    vel[: len(a), 0] = 1.0
    vel[len(a) :, 0], vel[len(a) :, 1] = -0.5, 0.4
    state = jaxmps.make_state(scene, pos, np.zeros(len(pos), int), velocity=vel)
    ids = np.r_[np.zeros(len(a), int), np.ones(len(b), int)]
    mass = jnp.asarray(np.r_[np.full(len(a), 1e3), np.full(len(b), 2e3)] * l0**dim)

    def observe(scene, s):
        x, v = s.position[: len(pos)], s.velocity[: len(pos)]
        if dim == 3:
            moment = jnp.cross(x, v)
        else:
            moment = (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0])[:, None]
        return dict(
            linear=jnp.sum(mass[:, None] * v, axis=0),
            angular=jnp.sum(mass[:, None] * moment, axis=0),
            energy=0.5 * jnp.sum(mass * jnp.sum(v**2, axis=-1)),
        )

    energy, momenta, spins = [], [], []
    for mu in (0.0, 0.5):
        case = jaxmps.add_rigid_bodies(
            scene, params, state, ids, density=[1000.0, 2000.0], mu_static=mu
        )
        n = round(0.4 / dt)
        out = jaxmps.simulate(*case, n, n // 20, observe=observe)
        assert out.result == jaxmps.Result.successful
        saved = {k: np.asarray(v) for k, v in out.saved.items()}
        np.testing.assert_allclose(saved["linear"] - saved["linear"][0], 0, atol=1e-9)
        turned = np.abs(saved["angular"] - saved["angular"][0]).max()
        assert turned < 1e-3 * np.abs(saved["angular"][0]).max()
        energy.append(saved["energy"][-1])
        masses = np.asarray([1e3, 2e3])[:, None] * 0.5**dim
        momenta.append(masses * np.asarray(out.state.rigid.velocity))
        spins.append(np.asarray(out.state.rigid.angular_velocity))
    start = np.asarray([[1.0] + [0.0] * (dim - 1), [-0.5, 0.4] + [0.0] * (dim - 2)])
    start = np.asarray([[1e3], [2e3]]) * 0.5**dim * start
    sideways = 2e3 * 0.5**dim * 0.4
    # frictionless: nothing along the face (x is the face's normal)
    np.testing.assert_allclose(momenta[0][:, 1:], start[:, 1:], atol=0.01 * sideways)
    spin = spins[0] if dim == 2 else spins[0][:, 1:]
    np.testing.assert_allclose(spin[0], spin[1], atol=0.05 * np.abs(spin).max())
    # with friction: less energy, the sideways impulse within mu x the normal one
    assert energy[1] < energy[0], energy
    impulse = momenta[1][1] - start[1]
    assert impulse[0] > 0
    assert np.linalg.norm(impulse[1:]) <= 0.5 * impulse[0], impulse


MUS = np.array([0.2, 0.4, 0.6, 0.8])


@pytest.fixture(scope="module")
def tilt_sweep():
    """One vmapped batch: for each mu, tan(theta) = 0.95 mu, 1.05 mu and 2 mu."""
    case = jaxmps.scenes.friction_tilt()
    ratios = np.array([0.95, 1.05, 2.0])
    mu = np.repeat(MUS, len(ratios))
    ratio = np.tile(ratios, len(MUS))
    theta = np.arctan(ratio * mu)
    gravity = np.stack([G * np.sin(theta), -G * np.cos(theta)], axis=1)
    t_end = 1.0
    n = round(t_end / float(case.params.dt))
    result = jaxmps.sweep(
        case,
        {
            "gravity": gravity,
            "rigid.mu_static": mu[:, None],
            "rigid.mu_kinetic": mu[:, None],
        },
        n_steps=n,
        save_every=n // 10,
    )
    assert np.all(np.asarray(result.result) == 0)
    x0 = float(case.state.rigid.centre[0, 0])
    dx = np.asarray(result.saved["block_x"])[:, -1] - x0
    accel = G * (np.sin(theta) - mu * np.cos(theta))
    return mu, ratio, dx, np.maximum(accel, 0.0) * t_end**2 / 2


def _two_blocks(viscosity, dt):
    l0 = 0.1
    a = geometry.block([0.0, 0.0], [0.5, 0.5], l0)
    b = geometry.block([0.8, 0.1], [1.3, 0.6], l0)
    pos = np.concatenate([a, b])
    scene = jaxmps.make_scene(pos, l0, ([-3, -3], [4, 4]), candidate_capacity=len(pos))
    params = jaxmps.make_params(2, dt=dt, gravity=0.0, viscosity=viscosity)
    vel = np.zeros_like(pos)
    vel[: len(a), 0], vel[len(a) :, 0] = 1.0, -0.5
    state = jaxmps.make_state(scene, pos, np.zeros(len(pos), int), velocity=vel)
    ids = np.r_[np.zeros(len(a), int), np.ones(len(b), int)]
    scene, params, state = jaxmps.add_rigid_bodies(
        scene, params, state, ids, density=[1000.0, 2000.0], friction=None
    )
    mass = jnp.asarray(np.r_[np.full(len(a), 1000.0), np.full(len(b), 2000.0)] * l0**2)

    def observe(scene, s):
        xa, xb = s.position[: len(a)], s.position[len(a) :]
        gap = jnp.min(jnp.linalg.norm(xa[:, None, :] - xb[None, :, :], axis=-1))
        x, v = s.position, s.velocity
        linear = jnp.sum(mass[:, None] * v, axis=0)
        angular = jnp.sum(mass * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]))
        return dict(
            gap=gap, linear=linear, angular=angular, spin=s.rigid.angular_velocity
        )

    n = round(0.6 / dt)
    out = jaxmps.simulate(scene, params, state, n, n // 20, observe=observe)
    assert out.result == jaxmps.Result.successful
    return {k: np.asarray(v) for k, v in out.saved.items()}


def _contact(n=(0.0, 1.0), force=(0.0, 1000.0), pressure_sum=2000.0):
    from jaxmps.bodies._friction import Contact

    return Contact(
        force=jnp.asarray([force]),
        normal=jnp.asarray([n]),
        touching=jnp.asarray([True]),
        pressure_sum=jnp.asarray([pressure_sum]),
        arm=jnp.asarray([[0.0, -0.5]]),
        wall_velocity=jnp.zeros((1, 2)),
    )


@pytest.mark.parametrize(
    "width, height",
    [
        pytest.param(1.0, 1.0, id="cube"),
        pytest.param(0.5, 1.0, id="tall", marks=pytest.mark.slow),
    ],
)
def test_block_tips_over_its_edge_only_beyond_the_static_limit(width, height):
    """With a friction too high to slide (mu = 1.5) and the friction torque on, a
    block on a slope suddenly tilted stays upright, and still, while the resultant
    of its weight falls inside its base, tan(theta) < (width - l0) / (height - l0)
    (1 for the cube, 0.44 for a block twice as tall as wide; here 0.97 of it), and
    tips over beyond it (1.03 of it). The contact face's normal forces give the
    restoring moment; with the friction at the contact point alone the tall block
    tipped at 0.95 of its limit, and without the contact force a cube toppled at
    0.76."""
    l0 = 0.1
    case = jaxmps.scenes.friction_tilt(
        block_size=width,
        block_height=height,
        friction_torque=True,
        mu_static=1.5,
        mu_kinetic=1.5,
    )
    limit = (width - l0) / (height - l0)
    theta = np.arctan(limit * np.asarray([0.97, 1.03]))
    gravity = np.stack([G * np.sin(theta), -G * np.cos(theta)], axis=1)
    n = round(2.0 / float(case.params.dt))
    n -= n % 20
    out = jaxmps.sweep(case, {"gravity": gravity}, n_steps=n, save_every=n // 20)
    angle = np.degrees(np.abs(np.asarray(out.saved["block_angle"])))
    x = np.asarray(out.saved["block_x"])
    assert angle[0].max() < 0.1, angle[0].max()  # upright
    assert np.abs(x[0] - float(case.state.rigid.centre[0, 0])).max() < 1e-4
    assert angle[1, -1] > 60.0, angle[1, -1]  # tipped over


def test_friction_torque_keeps_the_coulomb_law():
    """With the friction torque on, a block on its face follows the Coulomb law as
    without it: it stays exactly where it is at tan(theta) = 0.9 mu (it crept
    0.3 mm in 0.5 s with the law at the contact point alone) and slides at 1.1 mu
    within 5 % of g (sin - mu cos) t^2 / 2 (13 % too far before; measured 2.8 %
    here, the rest the floor lattice's roughness), upright in both."""
    mu, t_end = 0.5, 0.5
    case = jaxmps.scenes.friction_tilt(
        friction_torque=True, mu_static=mu, mu_kinetic=mu
    )
    theta = np.arctan(mu * np.asarray([0.9, 1.1]))
    gravity = np.stack([G * np.sin(theta), -G * np.cos(theta)], axis=1)
    out = jaxmps.sweep(case, {"gravity": gravity}, times=[t_end])
    assert np.all(np.asarray(out.result) == 0)
    dx = np.asarray(out.saved["block_x"])[:, -1] - float(case.state.rigid.centre[0, 0])
    angle = np.degrees(np.abs(np.asarray(out.saved["block_angle"])))
    theory = G * (np.sin(theta[1]) - mu * np.cos(theta[1])) * t_end**2 / 2
    assert abs(dx[0]) < 1e-5, dx[0]
    np.testing.assert_allclose(dx[1], theory, rtol=0.05)
    assert angle.max() < 0.05, angle.max()


def test_touching_blocks_in_still_water_stick_below_their_coefficient():
    """Two 0.5 m blocks side by side and touching, of twice the water's density,
    in 1 m of still water on a slope of tan(theta) = 0.5 = 0.91 mu with seed 002's
    submerged-weight normal force: each stays within 1 mm over 0.5 s, upright
    (measured about 0.1 mm each; with the friction at the contact point alone they
    crept 12.5-14.6 mm and tilted 0.7 degree)."""
    case = jaxmps.scenes.block_stack(
        layout="row",
        blocks=2,
        gap=0.0,
        angle=math.degrees(math.atan(0.5)),
        water_depth=1.0,
        floor_length=3.0,
        mu_static=0.55,
        friction_normal="submerged_weight",
    )
    out = jaxmps.simulate(
        case.scene,
        case.params,
        case.state,
        times=[0.25, 0.5],
        observe=lambda scene, state: state.rigid,
    )
    assert out.result == jaxmps.Result.successful
    travel = (
        np.asarray(out.saved.centre)[:, :, 0]
        - np.asarray(case.state.rigid.centre)[:, 0]
    )
    assert np.abs(travel).max() < 1e-3, travel
    assert np.degrees(np.abs(np.asarray(out.saved.orientation))).max() < 0.1


def test_stack_of_three_blocks_sticks_below_its_coefficient():
    """Two 0.5 x 0.25 m blocks stacked on a 2 m base (mu = 1.5 against the
    floor, 0.66 between the blocks) on a slope of tan(theta) = 0.6 = 0.91 mu,
    dry: over 1 s every block stays within 0.2 mm and upright (measured 0.00 /
    0.04 / 0.02 mm; with the friction between bodies resolved once per step,
    after the walls', 1.9 / 84 / 135 mm)."""
    case = jaxmps.scenes.block_stack(
        blocks=3,
        base_width=2.0,
        block_height=0.25,
        dt=0.001,
        angle=math.degrees(math.atan(0.6)),
    )
    mu = jnp.asarray([1.5, 0.66, 0.66])
    params = eqx.tree_at(
        lambda p: (p.rigid.mu_static, p.rigid.mu_kinetic), case.params, (mu, mu)
    )
    out = jaxmps.simulate(
        case.scene, params, case.state, 1000, 500, observe=lambda s, st: st.rigid
    )
    assert out.result == jaxmps.Result.successful
    travel = (
        np.asarray(out.saved.centre)[:, :, 0]
        - np.asarray(case.state.rigid.centre)[:, 0]
    )
    assert np.abs(travel).max() < 2e-4, travel
    assert np.degrees(np.abs(np.asarray(out.saved.orientation))).max() < 0.5


@pytest.mark.long
def test_block_on_block_sticks_below_and_slides_above_their_coefficient():
    """A 0.5 x 0.25 m block on a 2 m base block (mu = 1.5 against the floor) on a
    slope of tan(theta) = 0.6: with mu = 0.66 between them (the smaller of the
    two blocks' values) the top block stays (tan = 0.91 mu); with mu = 0.3 it
    slides over the base with g (sin - mu cos): within 5 % at 0.2 and 0.5 s
    (measured 1.03-1.05; a push along each pair of the two lattices slowed it
    to 0.77 at 0.5 s). The base stays put, and both blocks keep their shapes
    (T9)."""
    case = jaxmps.scenes.block_stack(
        base_width=2.0, block_height=0.25, dt=0.001, angle=math.degrees(math.atan(0.6))
    )
    start = np.asarray(case.state.rigid.centre)[:, 0]
    moved, finals = [], []
    for mu in ([1.5, 0.66], [1.5, 0.3]):
        mu = jnp.asarray(mu)
        params = eqx.tree_at(
            lambda p: (p.rigid.mu_static, p.rigid.mu_kinetic), case.params, (mu, mu)
        )
        out = jaxmps.simulate(
            case.scene,
            params,
            case.state,
            500,
            100,
            observe=lambda scene, s: s.rigid.centre[:, 0],
        )
        assert out.result == jaxmps.Result.successful
        moved.append(np.asarray(out.saved) - start)  # at 0.1, 0.2, ..., 0.5 s
        finals.append(out.state)
    stays, slides = moved
    theta = math.atan(0.6)
    for k in (1, 4):
        t = 0.1 * (k + 1)
        theory = G * (math.sin(theta) - 0.3 * math.cos(theta)) * t**2 / 2
        np.testing.assert_allclose(slides[k, 1], theory, rtol=0.05)
    assert np.abs(stays[:, 0]).max() < 1e-3 and np.abs(slides[:, 0]).max() < 1e-3
    assert np.abs(stays[:, 1]).max() < 1e-3, stays
    # seed 002 T9: the blocks stay rigid through contact and friction
    body = np.asarray(case.state.rigid.body)
    for k in (0, 1):
        x0 = np.asarray(case.state.position)[body == k]
        x1 = np.asarray(finals[1].position)[body == k]
        d0 = np.linalg.norm(x0[:, None] - x0[None], axis=-1)
        d1 = np.linalg.norm(x1[:, None] - x1[None], axis=-1)
        np.testing.assert_allclose(d1, d0, rtol=0, atol=1e-10 * d0.max())


@pytest.mark.long
def test_a_block_sliding_on_another_has_the_gradient_of_its_coulomb_law():
    """A 0.5 x 0.25 m block sliding on a 2 m base (tan = 0.6, mu = 0.3 between
    them): the reverse-mode derivative of its travel over 0.1 s with respect to
    that mu (the faces' couples and the friction's sweeps differentiated
    through) agrees with central differences (measured 7e-8 relative over
    0.2 s) and with g (sin - mu cos) t^2 / 2's -g cos t^2 / 2 within 1 %
    (0.04 %)."""
    case = jaxmps.scenes.block_stack(
        base_width=2.0, block_height=0.25, dt=0.001, angle=math.degrees(math.atan(0.6))
    )
    n = 100

    def travel(mu_top):
        mu = jnp.stack([jnp.asarray(1.5), mu_top])
        params = eqx.tree_at(
            lambda p: (p.rigid.mu_static, p.rigid.mu_kinetic), case.params, (mu, mu)
        )
        out = jaxmps.simulate(case.scene, params, case.state, n, n)
        return out.state.rigid.centre[1, 0] - case.state.rigid.centre[1, 0]

    grad = float(jax.grad(travel)(0.3))
    h = 1e-4
    fd = float((travel(0.3 + h) - travel(0.3 - h)) / (2 * h))
    np.testing.assert_allclose(grad, fd, rtol=1e-5)
    t = n * 1e-3
    theory = -G * math.cos(math.atan(0.6)) * t**2 / 2
    np.testing.assert_allclose(grad, theory, rtol=0.01)


def test_a_frictionless_block_slides_down_another_without_lattice_drag():
    """A 0.6 x 0.3 m block on a 3 m base block (l0 = 0.1 m), frictionless between
    them, under gravity tilted to tan(theta) = 0.7: it slides at g sin(theta), its
    travel within 3 % of g sin(theta) t^2 / 2 at 0.2 and 0.4 s, and it neither hops
    (normal speed under 0.05 m/s) nor rocks (spin under 0.2 rad/s). A push along
    each pair of the two lattices made a washboard of the contact: at l0 = 0.05 m
    a drag of 16 % of the drive, hops of 0.23 m/s and spins of 1 rad/s
    (validation/results/block_slide_cpu.md)."""
    tan = 0.7
    case = jaxmps.scenes.block_stack(
        block_size=0.6,
        block_height=0.3,
        base_width=3.0,
        floor_length=4.0,
        spacing=0.1,
        dt=0.001,
        mu_static=2.0,
        angle=math.degrees(math.atan(tan)),
    )
    mu = jnp.asarray([2.0, 0.0], case.params.rigid.mu_static.dtype)
    params = eqx.tree_at(
        lambda p: (p.rigid.mu_static, p.rigid.mu_kinetic), case.params, (mu, mu)
    )
    start = np.asarray(case.state.rigid.centre)[1, 0]

    def observe(scene, state):
        r = state.rigid
        return dict(x=r.centre[1, 0], v=r.velocity[1, 1], w=r.angular_velocity[1])

    out = jaxmps.simulate(case.scene, params, case.state, 400, 1, observe=observe)
    assert out.result == jaxmps.Result.successful
    saved = {k: np.asarray(v) for k, v in out.saved.items()}
    accel = G * math.sin(math.atan(tan))
    for k in (199, 399):
        t = (k + 1) * 1e-3
        np.testing.assert_allclose(saved["x"][k] - start, accel * t**2 / 2, rtol=0.03)
    assert np.abs(saved["v"]).max() < 0.05
    assert np.abs(saved["w"]).max() < 0.2


@pytest.mark.long
def test_a_block_slides_on_another_in_3d_with_the_whole_normal_force():
    """A 0.4 x 0.4 x 0.2 m block on a 2 x 1 x 0.2 m base (l0 = 0.1 m, both of
    twice the water's density, dry), mu = 0.3 between them, under gravity tilted
    to tan(theta) = 0.6: it slides with g (sin - mu cos), its travel within 5 %
    at 0.5 s. Friction that counted each touching particle's load along its own
    normal (a corner partner's leans 55 degrees) saw 0.9 of the normal force and
    let it slide 1.12 times as far."""
    l0, tan, mu = 0.1, 0.6, 0.3
    base = geometry.block([0.1, 0.1, 0.0], [2.1, 1.1, 0.2], l0)
    top = geometry.block([0.3, 0.4, 0.2], [0.7, 0.8, 0.4], l0)
    walls, kinds = geometry.tank([0.0, 0.0, 0.0], [2.2, 1.2, 0.6], l0, layers=3)
    position = np.concatenate([base, top, walls])
    kind = np.r_[np.zeros(len(base) + len(top), int), kinds]
    scene = jaxmps.make_scene(position, l0, ([-0.4] * 3, [2.6, 1.6, 1.0]))
    theta = math.atan(tan)
    gravity = jnp.asarray([G * math.sin(theta), 0.0, -G * math.cos(theta)])
    params = eqx.tree_at(lambda p: p.gravity, jaxmps.make_params(3, dt=1e-3), gravity)
    state = jaxmps.make_state(scene, position, kind)
    owner = np.r_[
        np.zeros(len(base), int), np.ones(len(top), int), np.full(len(walls), -1)
    ]
    scene, params, state = jaxmps.add_rigid_bodies(
        scene, params, state, owner, density=[2000.0, 2000.0], mu_static=[2.0, mu]
    )
    out = jaxmps.simulate(
        scene, params, state, 500, 500, observe=lambda sc, s: s.rigid.centre[:, 0]
    )
    assert out.result == jaxmps.Result.successful
    moved = np.asarray(out.saved)[-1] - np.asarray(state.rigid.centre)[:, 0]
    theory = G * (math.sin(theta) - mu * math.cos(theta)) * 0.5**2 / 2
    np.testing.assert_allclose(moved[1], theory, rtol=0.05)
    assert abs(moved[0]) < 1e-3


@pytest.mark.slow
def test_block_in_still_water_sticks_and_slides_with_its_submerged_weight():
    """Seed 002 T10: a 1 m square block of 1.5 x the water's density on a slope
    of tan(theta) = 0.5 in still water (1.5 m deep at the block, a 3 m tank),
    with the submerged-weight normal force (M - rho V) g cos(theta): it stays
    with mu = 0.55 (tan = 0.91 mu) and slides with mu = 0 and 0.25. The seed's
    acceleration (W / M)(sin - mu cos) g leaves out the water the block pushes
    aside; linear potential flow of this tank (validation/_slide_theory.py: the
    added mass at the release, 2.66 rho V, and the free surface's rise after it)
    gives travels of 22.66 and 11.33 mm over 0.3 s (the seed's formula: 65.8 and
    32.9). Asserted within T10's 10 %: measured 23.69 and 10.91 mm (1.046,
    0.963; 1.03-1.09 at l0 = 0.05 and 0.025 m and with `standard_ds`,
    validation/slide_in_water.py)."""
    theta = math.atan(0.5)
    case = jaxmps.scenes.friction_tilt(
        angle=math.degrees(theta),
        water_depth=1.5,
        floor_length=3.0,
        friction_normal="submerged_weight",
    )
    assert case.scene.rigid.pressure == "fluid"
    mus = np.asarray([0.0, 0.55, 0.25])
    n = round(0.3 / float(case.params.dt))
    out = jaxmps.sweep(
        case,
        {"rigid.mu_static": mus[:, None], "rigid.mu_kinetic": mus[:, None]},
        n_steps=n,
        save_every=n,
    )
    assert np.all(np.asarray(out.result) == 0)
    dx = np.asarray(out.saved["block_x"])[:, -1] - float(case.state.rigid.centre[0, 0])
    assert abs(dx[1]) < 1e-3, dx[1]
    np.testing.assert_allclose(dx[[0, 2]], [22.66e-3, 11.33e-3], rtol=0.1)


@pytest.mark.parametrize("mu", [0.5, 0.1])
def test_a_shaken_floor_carries_a_block_that_sticks_and_drags_one_that_slips(mu):
    """The floor (all walls) shaken along x, x_f = A sin(2 pi f t) with a peak
    acceleration A (2 pi f)^2 = 0.2 g. Friction acts on the block's velocity
    relative to the floor. At mu = 0.5 the block, at rest while the floor starts
    at v0 = 2 pi f A, slips until friction has brought it to the floor's speed,
    then sticks: it follows the floor (within 0.05 A) a distance behind it of
    about v0^2 / (2 mu g) (20 %). At mu = 0.1 it slips, dragged at no more than
    mu g (5 %) but dragged (its peak speed over half the floor's)."""
    from jaxmps._params import HarmonicParams
    from jaxmps.fluid import PrescribedMotion
    from jaxmps.fluid._motion import Harmonic

    case = jaxmps.scenes.friction_tilt(
        spacing=0.2, angle=0.0, mu_static=mu, mu_kinetic=mu, dt=2e-3
    )
    kind = np.asarray(case.state.kind)
    walls = np.flatnonzero(
        (kind == int(jaxmps.Kind.WALL)) | (kind == int(jaxmps.Kind.DUMMY))
    )
    frequency = 1.0
    amplitude = 0.2 * G / (2 * math.pi * frequency) ** 2
    motion = PrescribedMotion(
        particles=tuple(int(i) for i in walls), axis=(1.0, 0.0), law=Harmonic()
    )
    none = lambda x: x is None  # noqa: E731
    scene = eqx.tree_at(lambda s: s.motion, case.scene, motion, is_leaf=none)
    params = eqx.tree_at(
        lambda p: p.motion,
        case.params,
        HarmonicParams(amplitude=amplitude, frequency=frequency),
        is_leaf=none,
    )
    n, every = 750, 5
    out = jaxmps.simulate(scene, params, case.state, n, every)
    assert out.result == jaxmps.Result.successful
    t = np.asarray(out.saved.time)
    body = np.asarray(case.state.rigid.body)
    x = np.asarray(out.saved.position)[:, body == 0, 0].mean(axis=1)
    moved = x - np.asarray(case.state.position)[body == 0, 0].mean()
    floor = amplitude * np.sin(2 * math.pi * frequency * t)
    v = np.asarray(out.saved.velocity)[:, body == 0, 0].mean(axis=1)
    peak = amplitude * 2 * math.pi * frequency
    if mu * G > amplitude * (2 * math.pi * frequency) ** 2:
        behind = (floor - moved)[t > 0.2]
        assert np.ptp(behind) < 0.05 * amplitude
        assert np.mean(behind) == pytest.approx(peak**2 / (2 * mu * G), rel=0.2)
    else:
        assert np.max(np.abs(v)) > 0.5 * peak
        assert np.max(np.abs(np.diff(v) / np.diff(t))) < 1.05 * mu * G


def test_a_block_falls_past_a_convex_corner_one_spacing_away_untouched():
    """A dry block falling beside a step, its side face one spacing from the
    step's face (the lattice's resting distance, no overlap): as its side
    particles pass the step's top corner (a point, whose snapped normal is the
    diagonal) nothing pushes it, so it falls freely: no sideways velocity or spin,
    v_y = -g t. The corner particle's diagonal plane put a side particle 1.0 l0
    away, 40 degrees off that diagonal, 0.76 l0 from it, and the push (stiff as
    1/dt^2 on one particle in contact) threw the block sideways at metres per
    second in one step (`bodies._rigid._flat`)."""
    l0, dt, t_end = 0.1, 1e-3, 0.25
    walls, wall_kind = geometry.tank([-1.0, 0.0], [1.0, 1.5], l0)
    # the step: a wall layer on its top and side, dummies within
    step = geometry.block([0.0, 0.0], [0.5, 0.4], l0)
    inside = (step[:, 0] > 0.1) & (step[:, 1] < 0.3)
    step_kind = np.where(inside, int(jaxmps.Kind.DUMMY), int(jaxmps.Kind.WALL))
    box = geometry.block([-0.3, 0.5], [0.0, 0.8], l0)
    position = np.concatenate([box, step, walls])
    kind = np.concatenate([np.zeros(len(box), int), step_kind, wall_kind])
    scene = jaxmps.make_scene(position, l0, ([-1.5, -0.5], [1.5, 2.0]))
    params = jaxmps.make_params(2, dt=dt)
    state = jaxmps.make_state(scene, position, kind)
    body = np.r_[np.zeros(len(box), int), -np.ones(len(step) + len(walls), int)]
    scene, params, state = jaxmps.add_rigid_bodies(
        scene, params, state, body, density=1000.0
    )
    end = jaxmps.simulate(scene, params, state, round(t_end / dt)).state
    rigid = end.rigid
    # The walls' pressure on the side particles one spacing away pushes the
    # block off the step by about 5 % of its weight near the corner (2-3 cm/s);
    # the push off the chamfer was 0.3 m/s sideways, 5 rad/s and half of v_y.
    np.testing.assert_allclose(float(rigid.velocity[0, 1]), -9.81 * t_end, rtol=0.02)
    assert abs(float(rigid.velocity[0, 0])) < 0.05
    assert abs(float(rigid.angular_velocity[0, 0])) < 0.1
    # it passed the corner: its lowest side particle went below the step's top
    assert float(rigid.centre[0, 1]) - 0.1 < 0.4
