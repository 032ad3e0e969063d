"""Elastic bodies: the particle model of Koshizuka, Chikazawa & Oka (1999) as seed
000 §2.5.2 uses it (the digest's §5, with its errata), advanced after the fluid
stages like the rigid bodies."""

import dataclasses
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .._coupling import Coupling, FluidLoad
from .._numerics import (
    component_dot,
    einsum,
    is_concrete,
    matmul,
    pair_differences,
    pair_sum,
    safe_norm,
    take_rows,
)
from .._params import Params
from .._result import Result, update_result
from .._state import State
from .._types import Kind, Positions, Scalar, Velocities
from ..operators import Discretisation
from . import rotation as rot
from ._base import AbstractBodyModel
from ._friction import Contact, Coulomb, SubmergedWeight
from ._rigid import (
    _contact_magnitude,
    _flat,
    _outward,
    _wall_surface,
    reaction_on_partners,
    round_partners,
)

PairVectors = tuple[Float[Array, "m k"], ...]


def lame(youngs_modulus, poisson_ratio):
    """Lame's constants (lambda, mu) from E and nu: lambda = E nu / ((1 + nu)
    (1 - 2 nu)) (the digest's erratum: (1 - 2 nu), printed (1 + 2 nu)), mu = E /
    (2 (1 + nu))."""
    nu = poisson_ratio
    lam = youngs_modulus * nu / ((1 + nu) * (1 - 2 * nu))
    mu = youngs_modulus / (2 * (1 + nu))
    return lam, mu


def shear_speed(youngs_modulus, poisson_ratio, density):
    """The shear-wave speed sqrt(mu / rho) [m/s], which sets the elastic step
    limit (`ElasticBodies.courant`)."""
    _, mu = lame(youngs_modulus, poisson_ratio)
    return (mu / density) ** 0.5


def pressure_speed(youngs_modulus, poisson_ratio, density):
    """The P-wave speed sqrt((lambda + 2 mu) / rho) [m/s]."""
    lam, mu = lame(youngs_modulus, poisson_ratio)
    return ((lam + 2 * mu) / density) ** 0.5


class ElasticResponse(eqx.Module):
    """The internal forces of the elastic particles in one configuration.

    Attributes:
        acceleration: of each particle by its body's stresses [m/s^2], (m, d).
        torque: spin torque on each particle, T_i = 1/2 sum_j r_ij x F_ij with
            F_ij the shear force on i [N m, per unit depth in 2-D], (m, a).
        pressure: the elastic pressure p_i = -lambda eps_vol [Pa], (m,).
    """

    acceleration: Float[Array, "m d"]
    torque: Float[Array, "m a"]
    pressure: Float[Array, " m"]


def _reference_pairs(disc: Discretisation, reference, neighbours):
    """(r0, |r0|, w(|r0|)) of every reference pair: r0_ij = 0 and w = 0 on empty
    slots (`m` marks none), |r0| = r_e there."""
    listed = neighbours < reference.shape[0]
    r0 = tuple(
        jnp.where(listed, o, 0.0) for o in pair_differences(reference, neighbours)
    )
    distance = safe_norm(r0, listed, placeholder=disc.r_e)
    weight = disc.weight(distance, listed & (distance < disc.r_e), disc.r_e)
    return r0, distance, weight


def reference_density(disc: Discretisation, es) -> Float[Array, " m"]:
    """Each elastic particle's number density from its own body unstrained: the
    sum over its reference neighbours of w(|r0_ij|)."""
    _, _, weight = _reference_pairs(disc, es.reference, es.neighbours)
    return jnp.sum(weight, axis=1)


# Choice: directions in which a particle's reference neighbours are too few to
# measure a strain (A's eigenvalue below this, e.g. across a body one particle
# thick, where it is 0) keep the seed's uncorrected stiffness. A body two or more
# layers thick has every eigenvalue above 0.28 (3-D corners; 0.34 in 2-D).
CORRECTION_FLOOR = 0.25


def corrective_matrices(disc: Discretisation, reference, neighbours):
    """Each particle's corrective matrix C_i = A_i^-1, A_i = (d/n0) sum_j
    w(|r0_ij|) r0_ij r0_ij^T / |r0_ij|^2 over its reference neighbours, in the
    reference frame: the identity inside a regular lattice, and near a surface the
    inverse of the one-sided neighbourhood's deficit (a flat 2-D surface row:
    A = diag(0.85, 0.5)), so that a uniform strain reads the same at the surface
    as inside. Directions with an eigenvalue of A below `CORRECTION_FLOOR` are left
    uncorrected. A fixed property of the reference lattice (no gradient flows
    through it)."""
    r0, distance, weight = _reference_pairs(
        disc, jax.lax.stop_gradient(reference), neighbours
    )
    g = weight / distance**2
    dim = disc.dim
    a = jnp.stack(
        [
            jnp.stack([jnp.sum(g * r0[i] * r0[j], axis=1) for j in range(dim)], -1)
            for i in range(dim)
        ],
        -2,
    ) * (dim / disc.n0)
    value, vector = jnp.linalg.eigh(a)
    inverse = jnp.where(value >= CORRECTION_FLOOR, 1.0 / value, 1.0)
    return einsum("mij,mj,mkj->mik", vector, inverse, vector)


def _current_frame(correction, rotation, dim: int):
    """R_i C_i R_i^T: each particle's corrective matrix turned with it."""
    turn = rot.matrix(rotation, dim)
    return einsum("mij,mjk,mlk->mil", turn, correction, turn)


def _pair_rotation(rotation, neighbours, dim: int):
    """R_ij of every reference pair: R((theta_i + theta_j)/2) in 2-D, as its
    (cos, sin); in 3-D the mean of R(q_i) and R(q_j) (averaging quaternions would
    leave the unit sphere, seed 000 eq. 2.5-60), (m, k, d, d). Either way R_ji =
    R_ij, so u_ji = -u_ij."""
    if dim == 2:
        theta = 0.5 * (rotation[:, :1] + take_rows(rotation[:, 0], neighbours))
        return jnp.cos(theta), jnp.sin(theta)
    own = rot.matrix(rotation, dim)  # (m, d, d)
    return 0.5 * (own[:, None] + take_rows(own, neighbours))


def _turn(turn, vector: PairVectors, transpose: bool = False) -> PairVectors:
    """R_ij v_ij (R_ij^T v_ij with `transpose`) for every pair."""
    if isinstance(turn, tuple):
        c, s = turn
        s = -s if transpose else s
        return (c * vector[0] - s * vector[1], s * vector[0] + c * vector[1])
    dim = len(vector)
    if transpose:
        turn = jnp.swapaxes(turn, -1, -2)
    return tuple(
        sum(turn[:, :, a, b] * vector[b] for b in range(dim)) for a in range(dim)
    )


def pair_correction(correction, neighbours) -> Float[Array, "m k d d"]:
    """(C_i + C_j) / 2 of every reference pair, in the reference frame (the
    corrective matrices of `corrective_matrices`)."""
    return 0.5 * (correction[:, None] + take_rows(correction, neighbours))


def _corrected(pair, turn, u: PairVectors) -> PairVectors:
    """R_ij C_ij R_ij^T u_ij: the pair's corrective matrix turned with the pair."""
    local = _turn(turn, u, transpose=True)
    dim = len(u)
    local = tuple(
        sum(pair[:, :, a, b] * local[b] for b in range(dim)) for a in range(dim)
    )
    return _turn(turn, local)


def _strain(disc: Discretisation, reference, position, rotation, neighbours):
    """(u, r, g, R) of every reference pair: the strain displacement u_ij = r_ij -
    R_ij r0_ij, the current r_ij, w(|r0|) / |r0|^2 (0 on empty slots) and the
    pair rotation R_ij (`_pair_rotation`)."""
    listed = neighbours < reference.shape[0]
    r0, distance0, weight = _reference_pairs(disc, reference, neighbours)
    r = tuple(jnp.where(listed, o, 0.0) for o in pair_differences(position, neighbours))
    turn = _pair_rotation(rotation, neighbours, disc.dim)
    rotated = _turn(turn, r0)
    u = tuple(a - b for a, b in zip(r, rotated, strict=True))
    return u, r, weight / distance0**2, turn


def elastic_response(
    disc: Discretisation,
    lam: Float[Array, " m"],
    mu: Float[Array, " m"],
    density: Float[Array, " m"],
    reference: Float[Array, "m d"],
    position: Float[Array, "m d"],
    rotation: Float[Array, "m q"],
    neighbours: Int[Array, "m k"],
    correction: Float[Array, "m d d"] | None = None,
) -> ElasticResponse:
    """Seed 000 eq. 2.5-27...2.5-54 with the digest's signs: the strain
    displacement u_ij = r_ij - R_ij r0_ij, the pair stresses 2 mu u_ij / |r0|
    (normal and shear parts together: they share the coefficient), the elastic
    pressure p_i = -lambda (d/n0) sum u_ij . r_ij / |r0|^2 w(|r0|) and
    dv_i/dt = (2d / (rho n0)) sum [2 mu u_ij - P_ij r_ij] w(|r0|) / |r0|^2,
    P_ij = (p_i + p_j)/2 (compression, p > 0, pushes apart). The weights are at
    the reference distances, over the reference neighbours (`m` marks none).

    `correction` (`corrective_matrices`, None: the seed's model) replaces u_ij in
    the 2 mu term (and the spin torques) by R_ij C_ij R_ij^T u_ij, C_ij = (C_i +
    C_j) / 2 (`pair_correction`) turned with the pair: the same for i and j, so
    momentum and angular momentum stay exact, and the identity inside the body."""
    pair = None if correction is None else pair_correction(correction, neighbours)
    return _response(
        disc, lam, mu, density, reference, position, rotation, neighbours, pair
    )


def _response(
    disc, lam, mu, density, reference, position, rotation, neighbours, pair
) -> ElasticResponse:
    """`elastic_response` with the pairs' corrective matrices given (or None)."""
    dim, n0 = disc.dim, disc.n0
    u, r, g, turn = _strain(disc, reference, position, rotation, neighbours)
    shear_u = u if pair is None else _corrected(pair, turn, u)
    pressure = -lam * (dim / n0) * jnp.sum(component_dot(u, r) * g, axis=1)
    pair_pressure = 0.5 * (pressure[:, None] + take_rows(pressure, neighbours))
    scale = (2 * dim / n0) / density
    acceleration = scale[:, None] * (
        pair_sum(2 * mu[:, None] * g, shear_u) - pair_sum(pair_pressure * g, r)
    )
    # The shear force on i is m_i scale 2 mu u_s g; r x u_n = 0, so r x u will do.
    shear = disc.volume * (2 * dim / n0) * 2 * mu[:, None] * g
    u = shear_u
    if dim == 2:
        moment = r[0] * u[1] - r[1] * u[0]
        torque = 0.5 * jnp.sum(shear * moment, axis=1)[:, None]
    else:
        moments = (
            r[1] * u[2] - r[2] * u[1],
            r[2] * u[0] - r[0] * u[2],
            r[0] * u[1] - r[1] * u[0],
        )
        torque = 0.5 * jnp.stack([jnp.sum(shear * c, axis=1) for c in moments], -1)
    return ElasticResponse(acceleration=acceleration, torque=torque, pressure=pressure)


def elastic_stress(
    disc: Discretisation,
    mu: Float[Array, " m"],
    reference: Float[Array, "m d"],
    position: Float[Array, "m d"],
    rotation: Float[Array, "m q"],
    neighbours: Int[Array, "m k"],
    correction: Float[Array, "m d d"] | None = None,
) -> Float[Array, "m d d"]:
    """The deviatoric stress 2 mu eps_i of each particle [Pa] (the volumetric part,
    -p, is `elastic_response`'s pressure): 2 mu (d/n0) sum u_ij r_ij^T w / |r0|^2,
    times R_i C_i R_i^T with a `correction` (`corrective_matrices`), symmetrised."""
    u, r, g, _ = _strain(disc, reference, position, rotation, neighbours)
    scale = (disc.dim / disc.n0) * 2 * mu
    rows = [
        [scale * jnp.sum(g * u[a] * r[b], axis=1) for b in range(disc.dim)]
        for a in range(disc.dim)
    ]
    stress = jnp.stack([jnp.stack(row, -1) for row in rows], -2)
    if correction is not None:
        stress = matmul(stress, _current_frame(correction, rotation, disc.dim))
    return 0.5 * (stress + jnp.swapaxes(stress, -1, -2))


class ElasticBodies(AbstractBodyModel):
    """The elastic-body component of a Scene (Koshizuka et al. 1999; seed 000
    §2.5.2): each particle carries a position, velocity, rotation and spin; the
    stresses between reference neighbours (those within r_e in the unstrained body,
    fixed for the run) follow from the relative displacement with the pair's mean
    rotation removed, so large rotations carry no stress.

    In a step the fluid stages predict the body particles as fluid of the body's
    density (gravity, viscosity across the body's surface, none between particles
    of one body); `predict` adds the internal forces with symplectic Euler, in
    sub-steps of (largest step)/substeps (a shorter step takes fewer) over which
    that acceleration is held; the
    pressure then projects them with the fluid, its source seeing the body rigid
    within itself (`Coupling.reference_density`): it acts across the body's
    surface only, as the water's pressure and as contact with other bodies, and
    with walls unless `contact` is "push". Clamped particles are wall particles
    of the fluid that belong to a body: they hold the body and take part in its
    stresses at their reference positions.

    Attributes:
        count: number of bodies b.
        spacing: the bodies' particle spacing l0 [m].
        first: the number of the first body among all models' bodies (the rigid
            bodies are numbered first).
        substeps: elastic sub-steps per step (static).
        courant: the elastic stability limit C: a sub-step h must satisfy
            h <= C l0 / c_s, c_s = sqrt(mu / rho) the shear-wave speed
            (`time_step_limit`).
        wetted: whether fluid particles share the scene (the pressure couples
            the bodies to it); then the step itself must also satisfy
            dt <= coupling_courant l0 / c_s, sub-steps or not.
        coupling_courant: that limit's constant.
        pressure_courant: a sub-step must also satisfy h <= pressure_courant
            l0 / c_p, c_p = sqrt((lambda + 2 mu) / rho) the P-wave speed.
        surface_correction: whether the shear term carries each particle's
            corrective matrix (`corrective_matrices`); False gives the seed's
            model, whose surface particles are too soft.
        friction: the Coulomb law between the bodies' particles and walls
            (`Params.elastic.mu_static`, `mu_kinetic`), or None for frictionless
            contact (and no friction code compiled). See `advance`.
        contact_distance: a wall particle closer than this (in units of l0) to a
            body particle puts that particle in contact (as
            `RigidBodies.contact_distance`).
        contact: how the bodies meet walls (walls and dummies of no elastic
            body). "pressure": through the pressure, as the seed (the body's
            particles and the walls in each other's pressure source and force).
            "push": the pressure leaves those pairs out (`Coupling.apart`), and
            in each elastic sub-step h a particle within `contact_distance` of a
            wall takes the force max(k (l0 - g) - c v_n, 0) n, with n and g the
            facing walls' normal and the gap to their plane at the step's start
            (`_wall_surface`, as the rigid bodies' push) carried along with the
            particle's and the walls' motion, v_n its normal velocity relative
            to the walls, k = contact_stiffness m / h^2 and c = 2
            contact_damping sqrt(contact_stiffness) m / h (m the particle's
            mass).
        contact_stiffness, contact_damping: the push's kappa and damping ratio.
    """

    name: ClassVar[str] = "elastic"
    frame_fields: ClassVar[tuple[str, ...]] = ("rotation", "elastic_pressure")
    count: int
    spacing: float
    first: int = 0
    substeps: int = 1
    # Choice: the limit in the shear-wave speed, not the P-wave speed. Measured
    # (validation/elastic_cantilever.py, the stability map: an 8-layer beam, dt
    # split into sub-steps) the onset of instability lies at h c_s / l0 = 0.36-0.45
    # (nu = 0), 0.31-0.39 (0.3; 0.39-0.46 without the surface correction) and
    # 0.29-0.37 (0.48), while in c_p it moves from
    # 0.5-0.6 to 1.5-1.9: the fastest modes are shear and spin ones (the pressure
    # of a checkerboard mode is nil). In 3-D 0.34-0.41, 0.36-0.39 and 0.29-0.35;
    # at nu = 0.3 and E = 1e6 / 1e7 / 1e8 Pa under one gravity 0.35-0.40 each.
    # `add_elastic_bodies` takes half of it by default.
    courant: float = 0.25
    # Choice: the surface particles' shear term corrected (`corrective_matrices`)
    # by default. Without it (the seed's model) a particle on a flat surface reads
    # 85 % of an axial strain along it, and a beam bends as one about 0.34 l0
    # thinner: validation/elastic_cantilever.py, 8 layers, tip deflection +13.7 %
    # and period +7.4 % against Euler-Bernoulli; corrected +4.7 % and +3.0 %.
    # Correcting the elastic pressure as well made it worse (+5.0 % and +3.2 %),
    # and a scalar n_i in place of n0 overshot (-15 %, at every resolution).
    surface_correction: bool = True
    friction: Coulomb | None = None
    contact_distance: float = 1.5
    # Choice: "push" for dry bodies (`add_elastic_bodies`' "auto"). Through the
    # pressure the contact is a projection once per step that the sub-steps'
    # stresses drive against: seed 000's block impact (E = 1e6 Pa, nu = 0.48,
    # l0 = 0.1 m) left the floor with 0.59 / 1.9 / 2.5 times the kinetic energy
    # it came with at dt c_p / l0 = 0.09 / 0.47 / 0.94 (its bottom row turned
    # -1.0 m/s into +1.3 m/s in one step), and its impulse over that at
    # dt = 1e-4 s was 1.08 / 1.28 / 1.21 at dt = 2e-4 / 5e-4 / 1e-3 s. Pushed, at
    # the sub-step's own stiffness, it leaves with 0.67-0.73 of it and the
    # ratios are 1.00 / 1.00 / 0.99. Wetted bodies keep "pressure" by default:
    # leaving the wall pairs out of the pressure also takes them out of a wet
    # surface particle's number density.
    contact: str = "pressure"
    contact_stiffness: float = 0.2
    contact_damping: float = 0.7
    # Choice: a body the fluid touches takes the fluid's pressure once per step,
    # so the step itself (not a sub-step) must resolve its particles' stiffness.
    # Measured (a 4-layer plate under 0.1 m of water, nu = 0.3, E = 2.5e7 Pa):
    # calm at dt c_s / l0 = 0.24 and 1.0, noisy at 1.4 (particles at 1-2.5 m/s),
    # violent at 2 (8 m/s) and diverging at 3.9, whatever the sub-steps.
    wetted: bool = False
    coupling_courant: float = 0.5
    # Choice: a bound in the P-wave speed as well, which binds as nu -> 0.5
    # (c_p / c_s = 22 at nu = 0.499). Measured (the 8-layer beam at nu = 0.499):
    # stable at h c_p / l0 = 0.65-1.64, diverging at 2.8 (and at nu = 0.48 the
    # onset lies at 1.5-1.9, where the shear bound binds first).
    pressure_courant: float = 1.0

    def __check_init__(self):
        if self.count < 1:
            raise ValueError("ElasticBodies.count must be at least 1.")
        if self.substeps < 1:
            raise ValueError("ElasticBodies.substeps must be at least 1.")
        if not self.courant > 0:
            raise ValueError("ElasticBodies.courant must be positive.")
        if not self.coupling_courant > 0:
            raise ValueError("ElasticBodies.coupling_courant must be positive.")
        if not self.pressure_courant > 0:
            raise ValueError("ElasticBodies.pressure_courant must be positive.")
        if not self.contact_distance > 0:
            raise ValueError("ElasticBodies.contact_distance must be positive.")
        if self.contact not in ("pressure", "push"):
            raise ValueError(
                f"ElasticBodies.contact must be 'pressure' or 'push', got "
                f"{self.contact!r}."
            )
        if self.friction is not None and isinstance(
            self.friction.normal, SubmergedWeight
        ):
            raise ValueError(
                "ElasticBodies.friction: the normal force SubmergedWeight is a whole "
                "body's weight, and elastic friction acts particle by particle; use "
                "Coulomb(normal=ContactReaction()) (the default) or ContactPressure()."
            )

    def owner(self, state: State) -> Int[Array, " n"]:
        es = state.elastic
        n = state.position.shape[0]
        owner = jnp.full((n,), -1, es.body.dtype)
        return owner.at[es.index].set(es.body + self.first)

    def coupling(self, disc: Discretisation, params: Params, state: State) -> Coupling:
        es = state.elastic
        n = state.position.shape[0]
        density = jnp.full((n,), params.density, params.density.dtype)
        density = density.at[es.index].set(params.elastic.density[es.body])
        reference = jnp.full((n,), -1.0, density.dtype)
        reference = reference.at[es.index].set(reference_density(disc, es))
        apart = None
        if self.contact == "push":
            free = jnp.zeros((n,), bool).at[es.index].set(~es.clamped)
            apart = jnp.where(free, 1, jnp.where(self._solid(state), 2, 0))
        return Coupling(
            density=density,
            owner=self.owner(state),
            as_fluid=jnp.zeros((n,), bool),
            reference_density=reference,
            apart=apart,
        )

    def _solid(self, state: State):
        """Active wall and dummy particles that belong to no elastic body."""
        return (
            state.active
            & ((state.kind == int(Kind.WALL)) | (state.kind == int(Kind.DUMMY)))
            & (self.owner(state) < 0)
        )

    def _walls(self, disc: Discretisation, state: State, pairs):
        """Each elastic particle's wall surface (walls of no elastic body within
        `contact_distance`): the facing walls' normal, the gap to their plane,
        their mean velocity (`_wall_surface`, as the rigid bodies' contact), and
        whether it has one, shape (m, ...)."""
        solid = jnp.where(self._solid(state), 0, -1)
        outward = _outward(pairs, solid)
        rows, close = self._close(disc, state, pairs)
        normal, gap, v_wall = _wall_surface(
            close,
            rows,
            outward,
            state.velocity,
            disc.spacing,
            round_partners(state, rows),
            _flat(pairs, solid, outward, disc.spacing),
        )
        return normal, gap, v_wall, jnp.any(close, axis=1)

    def _close(self, disc: Discretisation, state: State, pairs):
        """The elastic particles' rows of the pairs, and which partners are walls
        of no elastic body within `contact_distance`, shape (m, k)."""
        wall = self._solid(state) & (state.kind == int(Kind.WALL))
        rows = jax.tree.map(lambda a: a[state.elastic.index], pairs)
        close = (
            rows.valid
            & take_rows(wall, rows.index)
            & (rows.distance < self.contact_distance * disc.spacing)
        )
        return rows, close

    def _wall_push(self, disc: Discretisation, state: State, pairs, rho, full):
        """The contact push's acceleration of each elastic particle as a function
        of its sub-step position, velocity and sub-step number (see `contact`):
        the facing walls' surface at the step's start, carried along with the
        particle's and the walls' motion."""
        es = state.elastic
        normal, gap, v_wall, near = self._walls(disc, state, pairs)
        near = near & ~es.clamped
        mass = rho * disc.volume

        def push(x, v, k):
            # the gap along the wall's normal as the particle and wall move
            moved = jnp.sum((x - es.position - k * full * v_wall) * normal, -1)
            depth = jnp.where(near, disc.spacing - (gap + moved), 0.0)
            v_n = jnp.sum((v - v_wall) * normal, -1)  # > 0: leaving
            force = _contact_magnitude(
                self.contact_stiffness,
                self.contact_damping,
                full,
                mass,
                jnp.maximum(depth, 0.0),
                v_n,
            )
            force = jnp.where(depth > 0, force, 0.0)
            return (force / mass)[:, None] * normal

        return push

    def time_step_limit(
        self, disc: Discretisation, params: Params, state: State
    ) -> Scalar:
        """The largest stable dt [s] (`limits`)."""
        del state
        e = params.elastic
        sub, coupled = self.limits(e.youngs_modulus, e.poisson_ratio, e.density)
        return disc.spacing * jnp.minimum(self.substeps * sub, coupled)

    def limits(self, youngs_modulus, poisson_ratio, density):
        """Per metre of l0 [s/m]: the largest stable sub-step, min over the bodies
        of min(courant / c_s, pressure_courant / c_p), and the largest step of a
        wetted body, coupling_courant / c_s (inf when dry). NumPy for NumPy
        inputs."""
        xp = np if isinstance(youngs_modulus, np.ndarray) else jnp
        c_s = shear_speed(youngs_modulus, poisson_ratio, density)
        c_p = pressure_speed(youngs_modulus, poisson_ratio, density)
        sub = xp.min(xp.minimum(self.courant / c_s, self.pressure_courant / c_p))
        coupled = xp.min(self.coupling_courant / c_s) if self.wetted else xp.inf
        return sub, coupled

    def check(self, params: Params, state: State) -> None:
        b, e = self.count, params.elastic
        for name in ("youngs_modulus", "poisson_ratio", "density"):
            shape = getattr(e, name).shape
            if shape != (b,):
                raise ValueError(
                    f"Params.elastic.{name} has shape {shape} but the Scene has {b} "
                    f"elastic bodies (expected ({b},)). For a batch of values use "
                    "`jaxmps.sweep` or `jax.vmap` over Params."
                )
        if self.friction is not None:
            for name in ("mu_static", "mu_kinetic"):
                value = getattr(e, name)
                if value is None or value.shape != (b,):
                    got = "None" if value is None else f"shape {value.shape}"
                    raise ValueError(
                        f"Params.elastic.{name} is {got}, but the elastic bodies "
                        f"have a friction law: give one coefficient per body (shape "
                        f"({b},)), e.g. add_elastic_bodies(..., friction=Coulomb(), "
                        f"mu_static=..., mu_kinetic=...)."
                    )
        if is_concrete(e.poisson_ratio):
            nu = np.asarray(e.poisson_ratio, np.float64)
            if not np.all((nu > -1) & (nu < 0.5)):
                raise ValueError(
                    "Params.elastic.poisson_ratio must lie in (-1, 0.5) (at 0.5 the "
                    f"body is incompressible and lambda infinite), got {nu.tolist()}."
                )
        self.check_time_step(params, state)

    def check_time_step(self, params: Params, state: State) -> None:
        """Refuse a concrete dt beyond the elastic limit (ValueError)."""
        e = params.elastic
        if not is_concrete(params.dt, e.youngs_modulus, e.poisson_ratio, e.density):
            return
        del state
        values = [
            np.asarray(v, np.float64)
            for v in (e.youngs_modulus, e.poisson_ratio, e.density)
        ]
        sub, coupled = self.limits(*values)
        dt, l0 = float(params.dt), self.spacing
        moduli = (
            f"youngs_modulus={values[0].tolist()}, poisson_ratio={values[1].tolist()}"
        )
        if dt > coupled * l0 * (1 + 1e-9) and coupled < self.substeps * sub:
            raise ValueError(
                f"Params.dt = {dt:.3g} s is beyond the limit {coupled * l0:.3g} s of "
                f"elastic bodies in a fluid (coupling_courant={self.coupling_courant} "
                f"x l0 / c_s, {moduli}): the fluid's pressure acts once per step, so "
                "sub-steps do not lift it. Lower dt or Params.elastic.youngs_modulus."
            )
        if dt > self.substeps * sub * l0 * (1 + 1e-9):
            raise ValueError(
                f"Params.dt = {dt:.3g} s is beyond the elastic bodies' stability "
                f"limit {self.substeps * sub * l0:.3g} s (substeps={self.substeps} x "
                f"l0 x min(courant={self.courant} / c_s, pressure_courant="
                f"{self.pressure_courant} / c_p), {moduli}): lower dt, lower "
                "Params.elastic.youngs_modulus, or take more elastic sub-steps per "
                "step (the scene setting `substeps`, or "
                "`add_elastic_bodies(..., substeps=...)`)."
            )

    def predict(
        self,
        disc: Discretisation,
        params: Params,
        state: State,
        velocity: Velocities,
        position: Positions,
        reference_dt: Scalar | None = None,
        pairs=None,
    ) -> tuple[State, Velocities, Positions]:
        """Add the internal forces to the fluid stages' prediction, before the
        pressure: from the step's start (x, v, rotation, spin), symplectic Euler
        sub-steps of h = reference_dt / substeps (the largest step's; a shorter
        step takes as many whole ones as fit and one part-step),
            v += h (a_fluid + a_elastic(x)),  x += h v,
            spin += h T / I,  rotation turned by h spin,
        with a_fluid = (u* - v^k) / dt the prediction's acceleration (gravity,
        viscosity) and I = m l0^2 / 6 (the digest's erratum); clamped particles
        stay put. The pressure then projects the bodies' velocities with the fluid's
        (contact with walls, other bodies and the water), and `advance` takes the
        corrected velocities and positions."""
        es, e, dim = state.elastic, params.elastic, disc.dim
        dt = params.dt
        # Choice: a fixed sub-step across uneven steps. Split evenly, a step
        # shortened to land on a save changes h; the periodic pattern (3.8, 3.8,
        # 3.8, 3.8, 2.4, 2.4 x 1e-5 s for saves every 0.2 ms) grew a spin mode of a
        # dense plate at 8 sub-steps to 1.8e4 rad/s; with a fixed h it is calm.
        largest = dt if reference_dt is None else jnp.maximum(reference_dt, dt)
        full = largest / self.substeps
        lam, mu = lame(e.youngs_modulus, e.poisson_ratio)
        lam, mu, rho = lam[es.body], mu[es.body], e.density[es.body]
        inertia = rho * disc.volume * disc.spacing**2 / 6.0
        fluid_accel = (velocity[es.index] - es.velocity) / dt
        free = ~es.clamped
        pair = (
            pair_correction(
                corrective_matrices(disc, es.reference, es.neighbours), es.neighbours
            )
            if self.surface_correction
            else None
        )

        push = (
            self._wall_push(disc, state, pairs, rho, full)
            if self.contact == "push"
            else None
        )

        def substep(carry, k):
            x, v, q, spin, pushed = carry
            h = jnp.clip(dt - k * full, 0.0, full)
            response = _response(
                disc, lam, mu, rho, es.reference, x, q, es.neighbours, pair
            )
            accel = fluid_accel + response.acceleration
            if push is not None:
                from_walls = push(x, v, k)
                accel = accel + from_walls
                pushed = pushed + h * from_walls
            v = jnp.where(free[:, None], v + h * accel, 0.0)
            x = jnp.where(free[:, None], x + h * v, es.reference)
            spin = spin + h * response.torque / inertia[:, None]
            spin = jnp.where(free[:, None], spin, 0.0)
            q = jnp.where(free[:, None], rot.rotate(q, h * spin, dim), q)
            return (x, v, q, spin, pushed), response.pressure

        carry = (
            es.position,
            es.velocity,
            es.rotation,
            es.angular_velocity,
            jnp.zeros_like(es.velocity),
        )
        (x, v, q, spin, pushed), pressure = jax.lax.scan(
            substep, carry, jnp.arange(self.substeps, dtype=dt.dtype)
        )
        contact_force = rho[:, None] * disc.volume * pushed / dt
        reaction = jnp.zeros_like(es.wall_push)
        if push is not None:  # on the walls that pushed (`_wall_push`'s partners)
            rows, close = self._close(disc, state, pairs)
            reaction = reaction_on_partners(
                close, rows.index, contact_force, reaction.shape[0]
            )
        elastic = dataclasses.replace(
            es,
            rotation=q,
            angular_velocity=spin,
            elastic_pressure=pressure[-1],
            contact_force=contact_force,
            wall_push=reaction,
        )
        return (
            dataclasses.replace(state, elastic=elastic),
            velocity.at[es.index].set(v),
            position.at[es.index].set(x),
        )

    def advance(
        self, disc: Discretisation, params: Params, state: State, load: FluidLoad
    ) -> State:
        """Take the bodies' particles as the pressure left them (`predict` added
        the internal forces), less the friction impulses of the particles that
        touch walls (`friction_impulse`), and flag a step beyond the elastic
        limit."""
        es = state.elastic
        limit = self.time_step_limit(disc, params, state)
        beyond = params.dt > limit * (1 + 1e-9)
        result = update_result(state.result, beyond, Result.step_too_large)
        position, velocity = state.position, state.velocity
        if self.friction is not None:
            impulse = self.friction_impulse(disc, params, state, load)
            mass = params.elastic.density[es.body] * disc.volume
            change = impulse / mass[:, None]
            velocity = velocity.at[es.index].add(change)
            position = position.at[es.index].add(params.dt * change)
        elastic = dataclasses.replace(
            es, position=position[es.index], velocity=velocity[es.index]
        )
        return dataclasses.replace(
            state, position=position, velocity=velocity, elastic=elastic, result=result
        )

    def friction_impulse(
        self, disc: Discretisation, params: Params, state: State, load: FluidLoad
    ) -> Float[Array, "m d"]:
        """The friction impulse on each elastic particle this step [N s] (seed 000
        §2.6 for elastic bodies: friction acts on the surface particles in
        contact, and the body's stresses carry it inward).

        A free particle with a wall particle (not of an elastic body) within
        `contact_distance` l0 takes the facing walls' normal n (`_walls`, the
        push's),
        as its normal force N the walls' contact push over the step
        (`ElasticState.contact_force`; with `contact="pressure"` its share of
        the walls' pressure reaction, `FluidLoad.wall_gradient`, or P_i
        l0^(d-1) with `ContactPressure`), and its
        velocity relative to them after the pressure, v_t along the wall. The
        `Coulomb` law then treats it as a body of mass m = rho l0^d: it sticks
        (v_t -> 0) where m |v_t| <= mu_s N dt, else loses mu_k N dt / m of v_t;
        `advance` moves it by dt times its change of velocity.

        # Choice: per particle, not per body. A body's friction is then the sum
        # of its contacting particles' (at most mu N of the whole contact face),
        # and where the face sticks and where it slips follows from the stresses
        # that reach each particle; the seed moves the contacting surface
        # particles by the corrective displacement and lets the stresses respond,
        # which this is in velocity form. Also putting a sticking particle back
        # where it was along the wall at the step's start (the seed's "does not
        # move from step k") was tried: an elastic block tilted to 0.9 of the
        # onset then slid 8.7 cm in 0.5 s instead of 4.8 (dt = 2e-3 s). The
        # impulse acts on the particle alone: no spin.
        """
        es, dim, l0 = state.elastic, disc.dim, disc.spacing
        normal, _, wall_velocity, near = self._walls(disc, state, load.pairs)
        touching = near & ~es.clamped
        force = -disc.volume * load.wall_gradient[es.index]
        if self.contact == "push":
            force = es.contact_force
        contact = Contact(
            force=force,
            normal=normal,
            touching=touching,
            pressure_sum=state.pressure[es.index],
            arm=jnp.zeros((es.index.shape[0], dim), normal.dtype),
            wall_velocity=wall_velocity,
        )
        e = params.elastic
        volume = jnp.full(es.body.shape, disc.volume, normal.dtype)
        impulse, _ = self.friction(
            contact,
            state.velocity[es.index] - contact.wall_velocity,
            e.density[es.body] * volume,
            volume,
            e.mu_static[es.body],
            e.mu_kinetic[es.body],
            params,
            l0,
            dim,
        )
        return jnp.where(touching[:, None], impulse, 0.0)
