"""Elastic bodies in air: a cantilever under gravity and a bar under a sinusoidal
displacement (seed 000 §2.5.2, §3.2)."""

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from .. import geometry
from .._build import add_elastic_bodies, make_state
from .._types import Kind
from ..bodies import ElasticBodies, lame, shear_speed
from ._case import Case
from ._common import (
    boundary_layers,
    case_params,
    case_scene,
    resolve,
    setting_length,
    velocity_scale,
    whole,
)
from ._probes import Displacement, ElasticAmplitude

ELASTIC_CANTILEVER = {
    "length": 0.2,
    "thickness": 0.02,
    "spacing": 0.0025,
    "dim": 2,
    "youngs_modulus": 1.0e7,
    "poisson_ratio": 0.3,
    "solid_density": 1000.0,
    "tip_velocity": 0.0,
    "end_velocity": 0.0,
    "end_length": 0.0,
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


def _with_bodies(c: dict, scene, params, state, body, clamped=None):
    """`add_elastic_bodies` with the scene settings' material (one body model)."""
    return add_elastic_bodies(
        scene,
        params,
        state,
        body,
        youngs_modulus=c["youngs_modulus"],
        poisson_ratio=c["poisson_ratio"],
        density=c["solid_density"],
        clamped=clamped,
    )


def elastic_cantilever(**overrides) -> Case:
    """A beam of `length` and `thickness` (a square section in 3-D) along x,
    clamped at x < 0 by as many particle layers as a wall has, bending under its
    weight; `tip_velocity` starts it with the vertical velocity
    tip_velocity (x / L)^2, `end_velocity` with the axial velocity end_velocity
    on the particles within `end_length` of the free end (its last layer at 0;
    seed 000 §3.2.2's momentum test). No fluid.

    Probes: `tip_x`, `tip_y` (`tip_z` in 3-D): the displacement of the free end's
    particles. `cantilever_theory` gives Euler-Bernoulli's answers. The largest
    step resolves the first mode (a 200th of its Euler-Bernoulli period); the
    elastic sub-steps keep within the elastic limit (`ElasticBodies`).
    """
    c = resolve("elastic_cantilever", ELASTIC_CANTILEVER, overrides)
    l0, dim = c["spacing"], int(c["dim"])
    length, t = setting_length(c, "length"), setting_length(c, "thickness")
    clamp = boundary_layers(c) * l0
    lower = [-clamp] + [0.0] * (dim - 1)
    upper = [length] + [t] * (dim - 1)
    position = geometry.block(lower, upper, l0)
    config = {**c, "length": length, "thickness": t}
    theory = cantilever_theory(config)
    # room for four times the static deflection, within two lengths (a softer
    # beam sags out of the domain, and the run stops saying so)
    room = max(0.5 * length, min(4 * theory["deflection"], 2 * length))
    domain = (
        np.asarray(lower) - room,
        np.asarray(upper) + room,
    )
    kind = np.full(len(position), int(Kind.FLUID), np.int32)
    scene = case_scene(c, position, domain, kind)
    # dt_max resolves the first mode (a 200th of its period), the given
    # velocities, and a fall by l0 (a soft beam's period is long)
    speed = max(
        0.2 * l0 / (theory["period"] / 200),
        velocity_scale(l0, c["gravity"]),
        abs(c["tip_velocity"]),
        abs(c["end_velocity"]),
    )
    params = case_params(c, dim, speed)
    x = position[:, 0]
    velocity = np.zeros_like(position)
    velocity[:, -1] = np.where(x > 0, c["tip_velocity"] * (x / length) ** 2, 0.0)
    end = x > length - max(c["end_length"], l0)
    velocity[:, 0] = np.where(end, c["end_velocity"], 0.0)
    state = make_state(scene, position, kind, velocity=velocity)
    body = np.zeros(len(position), int)
    scene, params, state = _with_bodies(c, scene, params, state, body, x < 0)
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


ELASTIC_BAR = {
    "width": 0.2,
    "length": 1.0,
    "wavelength": 0.64,
    "amplitude": 1.0e-4,
    "spacing": 0.01,
    "dim": 2,
    "youngs_modulus": 1.0e3,
    "poisson_ratio": 0.3,
    "solid_density": 1000.0,
    "gravity": 0.0,
    "t_end": 1.0e-3,
}


def bar_theory(config: dict) -> dict:
    """The `elastic_bar`'s analytic amplitudes along its axis (plane strain,
    u_y = A sin(k y), eps_yy = A k cos(k y)): the elastic pressure lambda A k and
    the normal stress 2 mu A k [Pa] (0.566 and 0.755 Pa for the seed's bar)."""
    lam, mu = lame(config["youngs_modulus"], config["poisson_ratio"])
    strain = config["amplitude"] * 2 * math.pi / config["wavelength"]
    return {"pressure": float(lam) * strain, "stress": 2 * float(mu) * strain}


def elastic_bar(**overrides) -> Case:
    """Seed 000 §3.2.1: a 2-D bar (`width` x `length`, its axis along y) given
    the axial displacement u_y = `amplitude` sin(2 pi y / `wavelength`) from its
    unstrained lattice, in air, run for `t_end` (one step: a static evaluation).

    Probes: `pressure_amplitude` (the largest |elastic pressure|) and
    `stress_amplitude` (the largest |2 mu eps_yy|) along the centreline, away from
    the ends by a tenth of the length each; `bar_theory` gives their analytic
    values.
    """
    c = resolve("elastic_bar", ELASTIC_BAR, overrides)
    l0 = c["spacing"]
    if c["dt"] == "adaptive" and c["dt_max"] is None:
        c = {**c, "dt_max": c["t_end"]}  # one step: a static evaluation
    if int(c["dim"]) != 2:
        raise ValueError("elastic_bar is a 2-D case (seed 000 §3.2.1); set dim=2.")
    width, length = setting_length(c, "width"), setting_length(c, "length")
    position = geometry.block([0.0, 0.0], [width, length], l0)
    kind = np.full(len(position), int(Kind.FLUID), np.int32)
    domain = (
        np.array([-0.5 * width, -0.1 * length]),
        np.array([1.5 * width, 1.1 * length]),
    )
    scene = case_scene(c, position, domain, kind)
    params = case_params(c, 2, 1.0)
    state = make_state(scene, position, kind)
    body = np.zeros(len(position), int)
    scene, params, state = _with_bodies(c, scene, params, state, body)
    k = 2 * math.pi / c["wavelength"]
    moved = position.copy()
    moved[:, 1] += c["amplitude"] * np.sin(k * position[:, 1])
    es = state.elastic
    moved_elastic = jnp.asarray(moved, state.position.dtype)
    state = dataclasses.replace(
        state,
        position=state.position.at[es.index].set(moved_elastic[np.asarray(es.index)]),
        elastic=dataclasses.replace(es, position=moved_elastic[np.asarray(es.index)]),
    )
    reference = np.asarray(es.reference)
    centre = np.abs(reference[:, 0] - 0.5 * width) < 0.6 * l0
    away = np.abs(reference[:, 1] - 0.5 * length) < 0.4 * length
    line = tuple(int(i) for i in np.nonzero(centre & away)[0])
    _, mu = lame(c["youngs_modulus"], c["poisson_ratio"])
    probes = (
        ElasticAmplitude("pressure_amplitude", line, "pressure"),
        ElasticAmplitude("stress_amplitude", line, "stress", 1, float(mu)),
    )
    config = {**c, "width": width, "length": length}
    return Case("elastic_bar", scene, params, state, probes, float(c["t_end"]), config)


ELASTIC_PLATE = {
    "span": 0.2,
    "thickness": 0.01,
    "depth": 0.1,
    "water": True,
    "spacing": 0.0025,
    "dim": 2,
    "youngs_modulus": 2.5e7,
    "poisson_ratio": 0.3,
    "solid_density": 1000.0,
    "t_end": 0.5,
}


def plate_theory(config: dict) -> dict:
    """Clamped-clamped plate under a uniform load (plane strain): the mid-span
    deflection q L^4 / (384 D) [m], D = E t^3 / (12 (1 - nu^2)), q = rho g H +
    rho_s g t (the water column and the plate's weight) [Pa]; and the first
    natural period in vacuo 2 pi / (22.373 / L^2 sqrt(D / (rho_s t))) [s]."""
    e, nu = config["youngs_modulus"], config["poisson_ratio"]
    span, t, g = config["span"], config["thickness"], config["gravity"]
    rigidity = e * t**3 / (12 * (1 - nu**2))
    water = config["density"] * g * config["depth"] if config.get("water", True) else 0
    load = water + config["solid_density"] * g * t
    omega = 22.373 / span**2 * math.sqrt(rigidity / (config["solid_density"] * t))
    return {
        "deflection": load * span**4 / (384 * rigidity),
        "load": load,
        "rigidity": rigidity,
        "period": 2 * math.pi / omega,
    }


def _wetted_step(c: dict) -> dict:
    """The settings with `dt_max` (where adaptive steps leave it unset) within the
    limit of a wetted elastic body (`ElasticBodies.coupling_courant`), with
    margin."""
    if c["dt"] != "adaptive" or c["dt_max"] is not None:
        return c
    speed = shear_speed(c["youngs_modulus"], c["poisson_ratio"], c["solid_density"])
    limit = ElasticBodies.coupling_courant * c["spacing"] / float(speed)
    return {**c, "dt_max": 0.9 * limit}


def elastic_plate(**overrides) -> Case:
    """A water column of `depth` standing on an elastic plate (`span` between the
    tank's walls, `thickness`) clamped at both ends under the walls, air below:
    the fluid presses the plate, the plate holds the fluid (2-D, plane strain).
    `water=False`: the plate alone under its weight. The largest step is within the
    limit of a wetted elastic body (`ElasticBodies.coupling_courant`).

    Probe `deflection`: the downward displacement of the plate's mid-span
    particles [m]; `plate_theory` gives the clamped-clamped plate's static
    answer, about which the plate, loaded at once, oscillates.
    """
    c = resolve("elastic_plate", ELASTIC_PLATE, overrides)
    l0 = c["spacing"]
    c = _wetted_step(c)
    if int(c["dim"]) != 2:
        raise ValueError("elastic_plate is a 2-D case; set dim=2.")
    span, t = setting_length(c, "span"), setting_length(c, "thickness")
    depth = setting_length(c, "depth") if c["water"] else 0.0
    layers = boundary_layers(c)
    pad = layers * l0
    height = whole(1.3 * depth, l0) if depth > 0 else 4 * l0
    fluid = geometry.block([0.0, 0.0], [span, depth], l0) if depth > 0 else None
    fluid = np.zeros((0, 2)) if fluid is None else fluid
    walls, wall_kind = geometry.tank([0.0, 0.0], [span, height], l0, layers=layers)
    side = walls[:, 1] > 0
    walls, wall_kind = walls[side], wall_kind[side]
    plate = geometry.block([-pad, -t], [span + pad, 0.0], l0)
    position = np.concatenate([fluid, plate, walls])
    kind = np.concatenate(
        [
            np.full(len(fluid) + len(plate), int(Kind.FLUID), np.int32),
            wall_kind,
        ]
    )
    body = np.full(len(position), -1)
    body[len(fluid) : len(fluid) + len(plate)] = 0
    x = position[:, 0]
    clamped = (body == 0) & ((x < 0) | (x > span))
    config = {**c, "span": span, "thickness": t, "depth": depth}
    theory = plate_theory(config)
    domain = (
        np.array([-pad - 2 * l0, -t - 4 * theory["deflection"] - 2 * l0]),
        np.array([span + pad + 2 * l0, height + 0.5 * height]),
    )
    scene = case_scene(c, position, domain, kind)
    params = case_params(c, 2, max(velocity_scale(depth, c["gravity"]), 1e-9))
    state = make_state(scene, position, kind)
    scene, params, state = _with_bodies(c, scene, params, state, body, clamped)
    mid = (np.abs(x - 0.5 * span) < 0.6 * l0) & (body == 0)
    mid &= np.abs(position[:, 1] + 0.5 * t) < 0.6 * l0
    particles = tuple(int(i) for i in np.nonzero(mid)[0])
    probes = (
        Displacement(
            "deflection", particles, 1, float(position[list(particles), 1].mean()), -1.0
        ),
    )
    return Case(
        "elastic_plate", scene, params, state, probes, float(c["t_end"]), config
    )


def oscillation_mean(times, values) -> tuple[float, float, float]:
    """(mean, period, periods) of an oscillation sampled at `times` (a plate or a
    beam released from rest swings about its static value): the least-squares fit
    of a + b cos(w t) + c sin(w t) with the w (scanned over periods from the
    window's length / 1.2 down to four samples) that leaves the least residual;
    its mean a, its period 2 pi / w and how many periods the window holds. A fit
    of the dominant mode, not a mean over crossings of the series' mean, which
    higher modes riding on it cross too. Needs 1.2 periods (ValueError)."""
    t, y = np.asarray(times, float), np.asarray(values, float)
    span = t[-1] - t[0]
    step = float(np.median(np.diff(t)))
    if not span > 4.8 * step:
        raise ValueError("oscillation_mean needs a longer series (20 samples or more).")
    best = None
    for omega in 2 * np.pi * np.linspace(1.2 / span, 0.25 / step, 4000):
        basis = np.stack([np.ones_like(t), np.cos(omega * t), np.sin(omega * t)], -1)
        coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
        residual = float(np.sum((basis @ coef - y) ** 2))
        if best is None or residual < best[0]:
            best = (residual, float(coef[0]), 2 * np.pi / omega)
    _, mean, period = best
    return mean, period, span / period


ELASTIC_GATE = {
    "column_width": 0.1,
    "column_height": 0.14,
    "length": 0.079,
    "thickness": 0.005,
    "gap": 0.0,
    "floor_length": 0.3,
    "spacing": 0.00125,
    "dim": 2,
    "youngs_modulus": 1.0e7,
    "poisson_ratio": 0.4,
    "solid_density": 1100.0,
    "t_end": 0.4,
}


def elastic_gate(**overrides) -> Case:
    """Antoci, Gallati & Sibilla (2007): a water column (`column_width` x
    `column_height`) held by a rubber gate (`length` x `thickness`) that hangs
    from a rigid wall, clamped at its top, its free end `gap` above the floor; at
    t = 0 the water, at rest, pushes the gate open and flows out beneath it over
    a floor `floor_length` long (2-D, plane strain). The wall above the gate is as
    thick as the gate, or as the walls' layers where those are thicker, and
    reaches the tank's top.

    Probes: `tip_x`, `tip_y`: the displacement of the gate's free end (the mean
    of its lowest row of particles) [m], to compare with the experiment's
    measured free-end displacements. The largest step is within the limit of a
    wetted elastic body (`ElasticBodies.coupling_courant`). A spacing that leaves
    fewer than two particles through the gate is refused (ValueError).
    """
    c = resolve("elastic_gate", ELASTIC_GATE, overrides)
    l0 = c["spacing"]
    if int(c["dim"]) != 2:
        raise ValueError("elastic_gate is a 2-D case (the experiment's); set dim=2.")
    c = _wetted_step(c)
    width, height = (
        setting_length(c, "column_width"),
        setting_length(c, "column_height"),
    )
    length, t = setting_length(c, "length"), setting_length(c, "thickness")
    if round(t / l0) < 2:
        raise ValueError(
            f"spacing={l0:g} m leaves {round(t / l0)} particle through the gate's "
            f"thickness={c['thickness']:g} m; a gate one particle thick does not "
            "bend as a beam: lower spacing to thickness / 2 or less."
        )
    gap = round(c["gap"] / l0) * l0
    floor = setting_length(c, "floor_length")
    layers = boundary_layers(c)
    clamp = layers * l0
    top = max(whole(1.2 * height, l0), gap + length + clamp + l0)
    fluid = geometry.block([0.0, 0.0], [width, height], l0)
    walls, wall_kind = geometry.tank([0.0, 0.0], [width + t + floor, top], l0, layers)
    # the gate with its clamped rows, and the wall above it: as thick as the
    # gate or the walls' layers; a pressure wall on the faces, dummies inside
    gate = geometry.block([width, gap], [width + t, gap + length + clamp], l0)
    thick = max(t, clamp)
    upper = geometry.block([width, gap + length], [width + thick, top], l0)
    upper = geometry.remove_overlaps(upper, gate, l0)
    face = (upper[:, 0] < width + l0) | (upper[:, 1] < gap + length + l0)
    face |= upper[:, 0] > width + thick - l0
    upper_kind = np.where(face, int(Kind.WALL), int(Kind.DUMMY)).astype(np.int32)
    position = np.concatenate([fluid, gate, walls, upper])
    kind = np.concatenate(
        [
            np.full(len(fluid) + len(gate), int(Kind.FLUID), np.int32),
            wall_kind,
            upper_kind,
        ]
    )
    body = np.full(len(position), -1)
    body[len(fluid) : len(fluid) + len(gate)] = 0
    y = position[:, 1]
    clamped = (body == 0) & (y > gap + length)
    pad = (layers + 2) * l0
    domain = (
        np.array([-pad, -pad]),
        np.array([width + t + floor + pad, 1.5 * top]),
    )
    scene = case_scene(c, position, domain, kind)
    params = case_params(c, 2, velocity_scale(height, c["gravity"]))
    state = make_state(scene, position, kind)
    scene, params, state = _with_bodies(c, scene, params, state, body, clamped)
    end = (body == 0) & (y < gap + l0)
    tip = tuple(int(i) for i in np.nonzero(end)[0])
    probes = tuple(
        Displacement(name, tip, axis, float(position[list(tip), axis].mean()))
        for axis, name in enumerate(("tip_x", "tip_y"))
    )
    config = {
        **c,
        "column_width": width,
        "column_height": height,
        "length": length,
        "thickness": t,
        "gap": gap,
        "floor_length": floor,
    }
    return Case("elastic_gate", scene, params, state, probes, float(c["t_end"]), config)
