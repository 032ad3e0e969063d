"""The laws of DEM grains (seed 002 §5): seed 002's parameter rules, the fluid's
drag and lift on a grain, and the spring-dashpot-slider contact (`Grains` in
`_grains.py` uses them)."""

import math

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._numerics import component_dot, safe_norm, take_rows
from .._params import Params
from .._types import Scalar

PairVectors = tuple[Float[Array, "m k"], ...]

# Schiller-Naumann's drag law holds up to this Reynolds number; beyond it
# C_D = 0.44 (seed 002 eq. 3.75-3.76).
NEWTON_REYNOLDS = 1000.0
NEWTON_DRAG = 0.44


def sphere_volume(diameter):
    """pi d^3 / 6 [m^3]: a grain is a sphere in 2-D as in 3-D (seed 002 §5.1:
    spheres moving in a plane)."""
    return math.pi / 6.0 * diameter**3


def damping_ratio(restitution):
    """The damping ratio zeta = -ln e / sqrt(pi^2 + ln^2 e) of a linear
    spring-dashpot contact whose binary collision rebounds with the coefficient of
    restitution e (1 for e -> 0, 0 for e = 1)."""
    log = jnp.log(restitution)
    return -log / jnp.sqrt(jnp.pi**2 + log**2)


def rule_stiffness(mass, dt):
    """Seed 002's stiffness rule (eq. 3.68): k_n = (pi^2 / 200) m / dt^2, the
    stiffness whose mass between two springs has a natural period of 20 dt
    [N/m]."""
    return (math.pi**2 / 200.0) * mass / dt**2


def rule_step(mass, stiffness):
    """Seed 002's DEM step (eq. 3.67): dt = (pi / 10) sqrt(m / (2 k_n)), a
    twentieth of the natural period of a mass between two springs [s]."""
    return (math.pi / 10.0) * (mass / (2.0 * stiffness)) ** 0.5


def seed_contact_parameters(
    diameter: float,
    submerged_ratio: float,
    dt: float,
    water_density: float = 1000.0,
    poisson_ratio: float = 0.3,
    damping: float = 1.0,
) -> dict[str, float]:
    """Seed 002's contact parameters (§5.3; the tests T4, T5): the submerged mass
    m = rho_w R pi d^3 / 6, k_n by `rule_stiffness`, k_s = k_n / (2 (1 + nu_p)),
    eta_n = alpha 2 sqrt(m k_n) (alpha = `damping`, 1 in the seed) and eta_s =
    eta_n / sqrt(2 (1 + nu_p))."""
    mass = water_density * submerged_ratio * sphere_volume(diameter)
    k_n = rule_stiffness(mass, dt)
    eta_n = damping * 2.0 * math.sqrt(mass * k_n)
    return {
        "mass": mass,
        "k_n": k_n,
        "k_s": k_n / (2.0 * (1.0 + poisson_ratio)),
        "eta_n": eta_n,
        "eta_s": eta_n / math.sqrt(2.0 * (1.0 + poisson_ratio)),
    }


def drag_coefficient(reynolds):
    """Schiller-Naumann: C_D = (24 / Re)(1 + 0.15 Re^0.687) up to Re = 1000, 0.44
    beyond (seed 002 eq. 3.75-3.76)."""
    reynolds = jnp.asarray(reynolds)
    safe = jnp.where(reynolds > 0, reynolds, 1.0)
    laminar = 24.0 / safe * (1.0 + 0.15 * safe**0.687)
    return jnp.where(reynolds > NEWTON_REYNOLDS, NEWTON_DRAG, laminar)


def fluid_force(
    relative: Float[Array, "m d"],
    diameter: Float[Array, " m"],
    density,
    viscosity,
    lift,
    up: Float[Array, " d"],
) -> Float[Array, "m d"]:
    """Drag and lift of the fluid on grains moving at `relative` = u_f - v
    through it [N] (seed 002 eq. 3.74-3.77): the drag 1/2 rho A C_D |du| du with
    A = pi d^2 / 4 and C_D of Re = |du| d / nu (`drag_coefficient`), written as
    3 pi rho nu d du (1 + 0.15 Re^0.687) in the Schiller-Naumann range so that it
    stays smooth at du = 0 (the Stokes drag); and the lift
    1/2 rho A C_L (|du|^2 up - (up . du) du).

    Choice: the seed's lift is 1/2 rho A C_L |du|^2 e_n with e_n the upward
    normal to the relative flow, which is undefined where the flow is vertical
    and jumps across it. The form here is the same for a horizontal flow, falls
    off as the flow turns vertical (|du|^2 sin of the angle to the vertical,
    times the upward normal), and is smooth everywhere.
    """
    speed = safe_norm(relative, jnp.ones(relative.shape[:-1], bool), placeholder=0.0)
    area = 0.25 * math.pi * diameter**2
    moving = speed > 0
    safe_nu = jnp.where(viscosity > 0, viscosity, 1.0)
    reynolds = jnp.where(viscosity > 0, speed * diameter / safe_nu, jnp.inf)
    safe_re = jnp.where(moving & (reynolds <= NEWTON_REYNOLDS), reynolds, 1.0)
    stokes = 3.0 * math.pi * density * viscosity * diameter
    laminar = stokes * (1.0 + 0.15 * jnp.where(moving, safe_re**0.687, 0.0))
    newton = 0.5 * density * area * NEWTON_DRAG * speed
    coefficient = jnp.where(reynolds > NEWTON_REYNOLDS, newton, laminar)
    drag = coefficient[:, None] * relative
    along = jnp.sum(relative * up[None, :], axis=-1)
    lifted = speed[:, None] ** 2 * up[None, :] - along[:, None] * relative
    return drag + (0.5 * density * lift * area)[:, None] * lifted


def wendland_like(distance, r_e):
    """Seed 002's fluid-velocity weight (eq. 3.79, sign corrected by the digest):
    w_s(r) = 1 - 5 (r/r_e)^4 + 4 (r/r_e)^5 for r < r_e, else 0."""
    q = jnp.clip(distance / r_e, 0.0, 1.0)
    return 1.0 - 5.0 * q**4 + 4.0 * q**5


class _Walls(eqx.Module):
    """The wall particles grains touch, as the step left them."""

    position: Float[Array, "w d"]
    velocity: Float[Array, "w d"]
    active: Bool[Array, " w"]
    diameter: float


class _Material(eqx.Module):
    """A step's contact constants: k_n, k_s [N/m], the damping ratio, the
    friction coefficient and each grain's mass [kg]; eta_n = 2 zeta sqrt(m*
    k_n), eta_s = eta_n / sqrt(2 (1 + nu_p))."""

    k_n: Scalar
    k_s: Scalar
    zeta: Scalar
    shear_damping: float  # eta_s / eta_n
    friction: Scalar
    mass: Float[Array, " m"]
    ramp: float = 0.0  # the dashpots engage over this share of the contact distance
    rolling: Scalar | float = 0.0  # the rolling resistance coefficient mu_r

    @classmethod
    def of(cls, model, params: Params, mass) -> "_Material":
        """The constants of `model` (a `Grains`) with `params`."""
        g = params.grains
        ratio = 2.0 * (1.0 + model.poisson_ratio)
        return cls(
            k_n=g.stiffness,
            k_s=g.stiffness / ratio,
            zeta=damping_ratio(g.restitution),
            shear_damping=1.0 / math.sqrt(ratio),
            friction=g.friction,
            mass=mass,
            ramp=model.dashpot_ramp,
            rolling=g.rolling,
        )


class Contacts(eqx.Module):
    """The contact forces on the grains in one configuration.

    Attributes:
        force: the sum of each grain's contact forces [N], (m, d).
        torque: the sum of their torques about its centre [N m], (m, a).
        shear: the slots' tangential springs after this sub-step [m], (d, m, k).
        count: each grain's contacts (overlapping partners), (m,).
        wall_force: the force the grains exert on each wall particle, each
            grain's share times its `reaction_weight`, (w, d); None where not asked.
    """

    force: Float[Array, "m d"]
    torque: Float[Array, "m a"]
    shear: Float[Array, "d m k"]
    count: Int[Array, " m"]
    wall_force: Float[Array, "w d"] | None = None


def _cross_2d(a: PairVectors, b: PairVectors) -> Float[Array, "m k"]:
    return a[0] * b[1] - a[1] * b[0]


def _cross_3d(a: PairVectors, b: PairVectors) -> PairVectors:
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def _rolling_torque(
    spin,
    spins,
    diameter,
    sizes,
    partner,
    is_wall,
    touching,
    normal,
    push,
    material: _Material,
    h,
) -> Float[Array, "m a"]:
    """The rolling resistance of each grain's contacts: a couple -mu_r R* F_n
    along the relative spin (its part normal to the contact in 3-D), R* = r_i
    r_j / (r_i + r_j) (the grain's own r against a wall), equal and opposite on
    the two partners. So that it stops a relative spin rather than reverses it
    within a sub-step, it is at most I* |w_rel| / (2 h), I* the pair's reduced
    moment of inertia (Ai et al. 2011's directional constant torque, capped)."""
    r_i = 0.5 * diameter[:, None]
    r_j = 0.5 * take_rows(sizes, partner)
    effective = jnp.where(is_wall, r_i, r_i * r_j / (r_i + r_j))
    inertia = 0.1 * material.mass * diameter**2
    i_i = inertia[:, None]
    i_j = take_rows(inertia, partner)
    reduced = jnp.where(is_wall, i_i, i_i * i_j / jnp.where(is_wall, 1.0, i_i + i_j))
    relative = tuple(
        spin[:, a, None] - take_rows(spins[:, a], partner) for a in range(spin.shape[1])
    )
    if len(relative) == 3:
        along = component_dot(relative, normal)
        relative = tuple(w - along * n for w, n in zip(relative, normal, strict=True))
    size = safe_norm(relative, touching, placeholder=0.0)
    limit = material.rolling * effective * push
    magnitude = jnp.minimum(limit, reduced * size / (2.0 * h))
    scale = jnp.where(
        touching & (size > 0), magnitude / jnp.where(size > 0, size, 1.0), 0.0
    )
    return jnp.stack([-jnp.sum(scale * w, axis=1) for w in relative], axis=-1)


def _wall_reaction(on_grain, weight, partner, pressing, m: int, w: int):
    """Newton's third law slot by slot: the force on each wall particle is minus
    the slots' forces on the grains that press it, each times its grain's
    `weight` (grain partners and empty slots drop), shape (w, d)."""
    target = jnp.where(pressing, partner - m, w)
    return jnp.stack(
        [
            jnp.zeros((w,), f.dtype).at[target].add(-f * weight[:, None], mode="drop")
            for f in on_grain
        ],
        axis=-1,
    )


def contact_forces(
    x: Float[Array, "m d"],
    v: Float[Array, "m d"],
    spin: Float[Array, "m a"],
    diameter: Float[Array, " m"],
    partner: Int[Array, "m k"],
    shear: Float[Array, "d m k"],
    walls: _Walls,
    material: _Material,
    h: Scalar,
    reaction_weight: Float[Array, " m"] | None = None,
) -> Contacts:
    """The contact forces and torques on the grains (see `Grains`), and the
    tangential springs integrated over a sub-step of `h` [s]. A slot holds a
    partner of the DEM set (grains 0..m-1, then walls); partners are spheres
    of their diameter (walls: `walls.diameter`), walls of infinite mass and no
    spin. With `reaction_weight` (one per grain), also the force on each wall
    particle: minus the slots' forces on the grains, each times its grain's
    weight."""
    m, dim = x.shape
    w = walls.position.shape[0]
    is_wall = partner >= m
    velocity = jnp.concatenate([v, walls.velocity])
    spins = jnp.concatenate([spin, jnp.zeros((w, spin.shape[1]), spin.dtype)])
    sizes = jnp.concatenate([diameter, jnp.full((w,), walls.diameter, diameter.dtype)])
    overlap, reach, touching, normal, radius_i, radius_j = _contact_geometry(
        x, walls.position, diameter, sizes, partner
    )
    relative = _contact_velocity(
        v, velocity, spin, spins, partner, normal, radius_i, radius_j
    )
    along = component_dot(relative, normal)
    tangential = tuple(r - along * n for r, n in zip(relative, normal, strict=True))
    push, eta_n = _normal_push(
        material, partner, is_wall, overlap, reach, touching, along
    )
    spring, friction = _tangential_friction(
        material, shear, normal, tangential, touching, push, eta_n, h
    )
    on_grain = [f - push * n for f, n in zip(friction, normal, strict=True)]
    force = jnp.stack([jnp.sum(f, axis=1) for f in on_grain], axis=-1)
    wall_force = None
    if reaction_weight is not None:
        pressing = is_wall & touching
        wall_force = _wall_reaction(on_grain, reaction_weight, partner, pressing, m, w)
    lever = tuple(radius_i * n for n in normal)
    if dim == 2:
        torque = jnp.sum(_cross_2d(lever, friction), axis=1)[:, None]
    else:
        torque = jnp.stack([jnp.sum(c, axis=1) for c in _cross_3d(lever, friction)], -1)
    torque = torque + _rolling_torque(
        spin,
        spins,
        diameter,
        sizes,
        partner,
        is_wall,
        touching,
        normal,
        push,
        material,
        h,
    )
    return Contacts(
        force=force,
        torque=torque,
        shear=jnp.stack(spring),
        count=jnp.sum(touching, axis=1, dtype=jnp.int32),
        wall_force=wall_force,
    )


def _contact_geometry(x, wall_position, diameter, sizes, partner):
    """Per slot: the overlap, the sum of radii, whether the pair touches, the unit
    normal towards the partner (components) and both levers to the contact
    point."""
    m, dim = x.shape
    listed = partner < m + wall_position.shape[0]
    position = jnp.concatenate([x, wall_position])
    offset = tuple(
        jnp.where(listed, take_rows(position[:, a], partner) - x[:, a, None], 0.0)
        for a in range(dim)
    )
    distance = safe_norm(offset, listed, placeholder=1.0)
    reach = 0.5 * (diameter[:, None] + take_rows(sizes, partner))
    overlap = reach - distance
    touching = listed & (overlap > 0)
    # Choice: each grain's lever reaches the middle of the overlap (r - delta/2),
    # so that both partners' levers end at one contact point and the contact
    # keeps angular momentum exactly (levers of r_i and r_j would miss it by the
    # overlap's moment of the tangential force).
    radius_i = 0.5 * diameter[:, None] - 0.5 * overlap
    radius_j = 0.5 * take_rows(sizes, partner) - 0.5 * overlap
    normal = tuple(jnp.where(touching, o / distance, 0.0) for o in offset)
    return overlap, reach, touching, normal, radius_i, radius_j


def _contact_velocity(v, velocity, spin, spins, partner, normal, radius_i, radius_j):
    """The contact points' relative velocity (components): their centres' and
    the spins' (the point of i at r_i n, that of j at -r_j n)."""
    dim = v.shape[1]
    relative = tuple(
        take_rows(velocity[:, a], partner) - v[:, a, None] for a in range(dim)
    )
    if dim == 2:
        turn = radius_i * spin[:, :1] + radius_j * take_rows(spins[:, 0], partner)
        return (relative[0] + turn * normal[1], relative[1] - turn * normal[0])
    turn = tuple(
        radius_i * spin[:, a, None] + radius_j * take_rows(spins[:, a], partner)
        for a in range(3)
    )
    return tuple(r - c for r, c in zip(relative, _cross_3d(turn, normal), strict=True))


def _normal_push(material, partner, is_wall, overlap, reach, touching, along):
    """The normal spring-dashpot's push per slot (never pulling) and its dashpot
    coefficient eta_n (zeta times critical damping on the reduced mass)."""
    mass_i = material.mass[:, None]
    mass_j = take_rows(material.mass, partner)
    reduced = jnp.where(
        is_wall, mass_i, mass_i * mass_j / jnp.where(is_wall, 1.0, mass_i + mass_j)
    )
    eta_n = 2.0 * material.zeta * jnp.sqrt(material.k_n * reduced)
    if material.ramp > 0:
        # The dashpots engage smoothly, so that the force does not jump when a
        # contact begins (`Grains.dashpot_ramp`).
        eta_n = eta_n * jnp.clip(overlap / (material.ramp * reach), 0.0, 1.0)
    push = jnp.where(
        touching, jnp.maximum(material.k_n * overlap - eta_n * along, 0.0), 0.0
    )
    return push, eta_n


def _tangential_friction(material, shear, normal, tangential, touching, push, eta_n, h):
    """The tangential spring after the sub-step (turned into the contact's
    tangent plane, extended by the sub-step's tangential motion, capped at the
    Coulomb limit) and the friction force, spring plus dashpot within mu push."""
    eta_s = material.shear_damping * eta_n
    normal_part = component_dot(tuple(shear), normal)
    held = tuple(s - normal_part * n for s, n in zip(shear, normal, strict=True))
    spring = tuple(
        jnp.where(touching, s + h * t, 0.0)
        for s, t in zip(held, tangential, strict=True)
    )
    limit = material.friction * push
    stretch = safe_norm(spring, touching, placeholder=0.0)
    cap = jnp.where(
        stretch * material.k_s > limit,
        limit / jnp.where(stretch > 0, material.k_s * stretch, 1.0),
        1.0,
    )
    spring = tuple(s * cap for s in spring)
    trial = tuple(
        material.k_s * s + eta_s * t for s, t in zip(spring, tangential, strict=True)
    )
    size = safe_norm(trial, touching, placeholder=0.0)
    scale = jnp.where(size > limit, limit / jnp.where(size > 0, size, 1.0), 1.0)
    friction = tuple(jnp.where(touching, f * scale, 0.0) for f in trial)
    return spring, friction
