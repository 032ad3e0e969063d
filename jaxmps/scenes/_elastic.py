"""Elastic bodies in air: a cantilever under gravity (seed 000 §2.5.2, §3.2)."""

import math

import numpy as np

from .. import geometry
from .._build import add_elastic_bodies, make_state
from .._types import Kind
from ._case import Case
from ._common import boundary_layers, case_params, case_scene, resolve, whole
from ._probes import Displacement

ELASTIC_CANTILEVER = {
    "length": 0.2,
    "thickness": 0.02,
    "spacing": 0.0025,
    "dim": 2,
    "youngs_modulus": 1.0e7,
    "poisson_ratio": 0.3,
    "solid_density": 1000.0,
    "tip_velocity": 0.0,
    "t_end": 0.5,
}

# The first root of 1 + cos(x) cosh(x) = 0 (a clamped-free beam's first mode).
FIRST_MODE = 1.8751040687


def cantilever_theory(config: dict) -> dict:
    """Euler-Bernoulli for the `elastic_cantilever` settings: the static tip
    deflection under its weight q L^4 / (8 E' I) [m] and the first natural period
    2 pi / (1.8751^2 sqrt(E' I / (rho A L^4))) [s], with E' = E / (1 - nu^2) in
    2-D (the particle model in 2-D is plane strain) and E in 3-D (a square
    section)."""
    e, nu = config["youngs_modulus"], config["poisson_ratio"]
    length, t = config["length"], config["thickness"]
    rho, g = config["solid_density"], config["gravity"]
    stiff = e / (1 - nu**2) if int(config["dim"]) == 2 else e
    area = t if int(config["dim"]) == 2 else t * t
    inertia = area * t**2 / 12
    deflection = rho * g * area * length**4 / (8 * stiff * inertia)
    omega = FIRST_MODE**2 * math.sqrt(stiff * inertia / (rho * area * length**4))
    return {"deflection": deflection, "period": 2 * math.pi / omega}


def elastic_cantilever(**overrides) -> Case:
    """A beam of `length` and `thickness` (a square section in 3-D) along x,
    clamped at x < 0 by as many particle layers as a wall has, bending under its
    weight; `tip_velocity` starts it with the vertical velocity
    tip_velocity (x / L)^2. No fluid.

    Probes: `tip_x`, `tip_y` (`tip_z` in 3-D): the displacement of the free end's
    particles. `cantilever_theory` gives Euler-Bernoulli's answers. The largest
    step resolves the first mode (a 200th of its Euler-Bernoulli period); the
    elastic sub-steps keep within the elastic limit (`ElasticBodies`).
    """
    c = resolve("elastic_cantilever", ELASTIC_CANTILEVER, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    length, t = whole(c["length"], l0), whole(c["thickness"], l0)
    clamp = boundary_layers(c) * l0
    lower = [-clamp] + [0.0] * (dim - 1)
    upper = [length] + [t] * (dim - 1)
    position = geometry.block(lower, upper, l0)
    config = {**c, "length": length, "thickness": t}
    theory = cantilever_theory(config)
    room = max(0.5 * length, 4 * theory["deflection"])
    domain = (
        np.asarray(lower) - room,
        np.asarray(upper) + room,
    )
    kind = np.full(len(position), int(Kind.FLUID), np.int32)
    scene = case_scene(c, position, domain, kind)
    speed = 0.2 * l0 / (theory["period"] / 200)  # dt_max = period / 200
    params = case_params(c, dim, speed)
    x = position[:, 0]
    velocity = np.zeros_like(position)
    velocity[:, -1] = np.where(x > 0, c["tip_velocity"] * (x / length) ** 2, 0.0)
    state = make_state(scene, position, kind, velocity=velocity)
    scene, params, state = add_elastic_bodies(
        scene,
        params,
        state,
        np.zeros(len(position), int),
        youngs_modulus=c["youngs_modulus"],
        poisson_ratio=c["poisson_ratio"],
        density=c["solid_density"],
        clamped=x < 0,
    )
    tip = tuple(int(i) for i in np.nonzero(x > length - l0)[0])
    names = ("tip_x", "tip_y") if dim == 2 else ("tip_x", "tip_y", "tip_z")
    probes = tuple(
        Displacement(name, tip, axis, float(position[list(tip), axis].mean()))
        for axis, name in enumerate(names)
    )
    return Case(
        name="elastic_cantilever",
        scene=scene,
        params=params,
        state=state,
        probes=probes,
        t_end=float(c["t_end"]),
        config=config,
    )
