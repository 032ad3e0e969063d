"""Probes: jittable functions of the state that runs save over time."""

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._numerics import matmul, safe_norm
from .._scene import Scene
from .._state import State
from .._types import Kind
from ..bodies import corrective_matrices, elastic_stress
from ..bodies.rotation import matrix as rotation_matrix
from ..fluid import porosity_field


class AbstractProbe(eqx.Module):
    """A named scalar measurement of a State, evaluated inside `simulate`."""

    name: eqx.AbstractVar[str]

    @abc.abstractmethod
    def __call__(self, scene: Scene, state: State) -> Float[Array, ""]:
        """The probe's value for this state."""


class FrontPosition(AbstractProbe):
    """Surge-front position [m] from `x_start`: the fluid within `band` of the floor is
    binned into bins of width 2 l0 from `x_start`; the front is the largest x (plus
    l0/2) in the last bin of the contiguous occupied run. Detached splash ahead of
    that run is ignored. (Bins of 2 l0 so that a slightly disordered bottom row,
    which can leave a bin of width l0 empty, does not cut the run.)
    """

    name: str
    x_start: float
    floor: float
    band: float
    spacing: float
    n_bins: int

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        x = state.position[:, 0] - self.x_start
        hit = fluid & (state.position[:, -1] < self.floor + self.band) & (x >= 0)
        width = 2.0 * self.spacing
        b = jnp.clip(jnp.floor(x / width), 0, self.n_bins - 1).astype(jnp.int32)
        occupied = jnp.zeros(self.n_bins, bool).at[b].max(hit)
        run = jnp.sum(jnp.cumprod(occupied.astype(jnp.int32)))
        in_last = hit & (b == run - 1)
        front = jnp.max(jnp.where(in_last, x, -jnp.inf)) + 0.5 * self.spacing
        return jnp.where(run > 0, front, 0.0)


class FluidCount(AbstractProbe):
    """Number of active fluid particles (mass in units of one particle)."""

    name: str

    def __call__(self, scene: Scene, state: State) -> Float[Array, ""]:
        del scene
        fluid = state.active & (state.kind == int(Kind.FLUID))
        return jnp.sum(fluid).astype(state.position.dtype)


class WaterLevel(AbstractProbe):
    """Height of the highest fluid particle within 3 l0 / 4 of `x` (first axis)
    plus l0/2, measured from `floor` [m]; zero when the column is dry. The window
    holds one lattice column where `x` is on it and both where it lies between
    two (a window of l0 / 2 would hold neither, or one by round-off, midway), and
    a column stays in it while it sways by less than l0 / 4."""

    name: str
    x: float
    floor: float
    spacing: float

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        near = jnp.abs(state.position[:, 0] - self.x) <= 0.75 * self.spacing
        top = jnp.max(jnp.where(fluid & near, state.position[:, -1], -jnp.inf))
        level = top + 0.5 * self.spacing - self.floor
        return jnp.where(jnp.isfinite(level), level, 0.0)


class ColumnDepth(AbstractProbe):
    """Depth [m] of the water over `point` (its first coordinates: x, or x and y)
    above `floor`, counted by volume: each fluid particle holds l0^d, weighted by
    a tent 2 l0 wide about the point along each of those axes (1 over it, 0 one
    spacing off), so a lattice column reads its depth wherever the point falls
    between columns, and a moving particle enters and leaves smoothly. Spray
    over the column adds at most l0 per particle where `WaterLevel`'s highest
    particle would read its height; a floating body does not count."""

    name: str
    point: tuple[float, ...]
    floor: float
    spacing: float

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        weight = (fluid & (state.position[:, -1] > self.floor)).astype(
            state.position.dtype
        )
        for axis, at in enumerate(self.point):
            off = jnp.abs(state.position[:, axis] - at) / self.spacing
            weight = weight * jnp.maximum(1.0 - off, 0.0)
        return jnp.sum(weight) * self.spacing


class FlowVelocity(AbstractProbe):
    """Mean velocity component `axis` of the fluid within l0/2 of `x` (first axis)
    [m/s], over the whole column (and, in 3-D, the whole width); zero where it is
    dry."""

    name: str
    x: float
    spacing: float
    axis: int = 0

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        near = fluid & (jnp.abs(state.position[:, 0] - self.x) < 0.5 * self.spacing)
        total = jnp.sum(jnp.where(near, state.velocity[:, self.axis], 0.0))
        return total / jnp.maximum(jnp.sum(near), 1)


class PressureAt(AbstractProbe):
    """Mean pressure [Pa] of a fixed set of particles (wall points, or fluid points
    chosen at build time)."""

    name: str
    indices: tuple[int, ...]

    def __call__(self, scene: Scene, state: State):
        del scene
        return jnp.mean(state.pressure[jnp.asarray(self.indices)])


class FluidPressureNear(AbstractProbe):
    """Mean pressure [Pa] of the active fluid particles within `radius` of `point`."""

    name: str
    point: tuple[float, ...]
    radius: float

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        d = (
            state.position
            - jnp.asarray(self.point, dtype=state.position.dtype)[None, :]
        )
        near = fluid & (jnp.sum(d * d, axis=-1) < self.radius**2)
        count = jnp.sum(near)
        total = jnp.sum(jnp.where(near, state.pressure, 0.0))
        return jnp.where(count > 0, total / jnp.maximum(count, 1), jnp.nan)


def observe_probes(probes: tuple[AbstractProbe, ...]):
    """An `observe` function for `simulate` returning {"time": t, name: value, ...}."""
    return _ProbeObserver(probes=probes)


class _ProbeObserver(eqx.Module):
    probes: tuple[AbstractProbe, ...]

    def __call__(self, scene: Scene, state: State):
        out = {"time": state.time}
        for probe in self.probes:
            out[probe.name] = probe(scene, state)
        return out


class StripLevel(AbstractProbe):
    """Mean water depth [m] over the strip |x - `x`| < `width`/2 from the fluid volume
    it holds (particle count x l0^(d-1) / width; 2-D), minus `still_depth`: a
    smoother surface-elevation gauge than the highest particle.

    With `softness` > 0 the strip edges are smoothed over `softness` x l0 (each
    particle counts sigmoid((width/2 - |x_j - x|) / (softness l0))), so the probe
    is a differentiable function of the positions: use it as a calibration target.
    The volume is then divided by the weight's integral, 2 s ln(1 + e^(width/2s))
    = width + 2 s ln(1 + e^(-width/2s)) with s = softness l0: `width` alone would
    read a level surface 6 % high at a width of 4 l0 and softness 1, 31 % at 2 l0.
    With `anchor`, `x` is in the frame of that (moving) wall particle, initially at
    x = `anchor_x`: a gauge fixed to a shaken tank. In porous regions with a
    porosity phi < 1 a particle counts 1/phi(x) of its volume (`fluid.porosity_field`,
    in the tank's frame): the probe reads the free surface's height, as a gauge
    over rock does, not the water's volume.
    """

    name: str
    x: float
    width: float
    spacing: float
    still_depth: float
    softness: float = 0.0
    anchor: int | None = None
    anchor_x: float = 0.0

    def __call__(self, scene: Scene, state: State):
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        x = _tank_frame(state, self.anchor, self.anchor_x)
        if scene.porous is not None and scene.porous.porous:
            frame = state.position.at[:, 0].set(x)
            shift = jnp.zeros(state.position.shape[1:], state.position.dtype)
            volume = 1.0 / porosity_field(scene.porous, shift, frame)
        else:
            volume = 1.0
        inside = 0.5 * self.width - jnp.abs(x - self.x)
        if self.softness > 0:
            s = self.softness * self.spacing
            weight = jax.nn.sigmoid(inside / s)
            width = self.width + 2 * s * math.log1p(math.exp(-0.5 * self.width / s))
        else:
            weight = (inside > 0).astype(state.position.dtype)
            width = self.width
        area = jnp.sum(jnp.where(fluid, weight * volume, 0.0)) * self.spacing**2
        return area / width - self.still_depth


class PressureLevel(AbstractProbe):
    """Height [m] above `floor` at which the hydrostatic pressure of the fluid in the
    strip |x - `x`| < `width`/2 falls to zero: the mean of z_j + P_j / (rho g) over
    the strip's fluid particles deeper than `below` under its highest one. It is
    the free surface that the pressure sees (P = 0 is imposed at the surface
    particles' centres, and the pressure field extrapolates to zero a little below
    them), and so the level that Archimedes' draft is measured from.
    """

    name: str
    x: float
    width: float
    floor: float
    rho_g: float
    below: float

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        strip = fluid & (jnp.abs(state.position[:, 0] - self.x) < 0.5 * self.width)
        z = state.position[:, -1]
        top = jnp.max(jnp.where(strip, z, -jnp.inf))
        deep = strip & (z < top - self.below)
        count = jnp.sum(deep)
        level = z + state.pressure / self.rho_g
        mean = jnp.sum(jnp.where(deep, level, 0.0)) / jnp.maximum(count, 1)
        return jnp.where(count > 0, mean - self.floor, 0.0)


class DisplacedDepth(AbstractProbe):
    """The depth of water a floating body displaces [m], counted by mass: the
    water per unit plan area in the columns far from the body (|x - x_far| <
    `far_width`/2 for each `far` centre) minus that in the columns under the
    body (|x - x_body| < `width`/2), in particle volumes l0^d. Water at rest
    presses on the floor with the weight of each column, the body's included, so
    a body of mass m and plan area A floating in equilibrium displaces
    m / (rho A): `density_ratio` x `box_height` for a box (Archimedes by mass,
    independent of where its free surface or its faces are taken to lie).
    Columns span the tank across (3-D: `across` [m]; 2-D: 1)."""

    name: str
    body: int
    width: float
    far: tuple[float, ...]
    far_width: float
    volume: float
    across: float = 1.0

    def __call__(self, scene: Scene, state: State):
        del scene
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        x = state.position[:, 0]
        centre = state.rigid.centre[self.body, 0]
        under = fluid & (jnp.abs(x - centre) < 0.5 * self.width)
        far = jnp.zeros_like(fluid)
        for x_far in self.far:
            far = far | (fluid & (jnp.abs(x - x_far) < 0.5 * self.far_width))
        per_area = self.volume / self.across
        far_depth = jnp.sum(far) * per_area / (len(self.far) * self.far_width)
        return far_depth - jnp.sum(under) * per_area / self.width


def _tank_frame(
    state: State, anchor: int | None, anchor_x: float
) -> Float[Array, " n"]:
    """Particle x in the frame that moves with particle `anchor` (initially at
    `anchor_x`); the lab frame when `anchor` is None."""
    x = state.position[:, 0]
    if anchor is None:
        return x
    return x - (state.position[anchor, 0] - anchor_x)


class BodyValue(AbstractProbe):
    """One component of a rigid body's state: `field` is "centre", "velocity",
    "force" (gravity excluded), "contact_force", "friction", "impulse" (time
    integral of "force"; component `axis`), "angular_velocity", "torque",
    "angular_impulse" (2-D: about z; 3-D: component `axis`) or
    "angle" (2-D: the rotation angle [rad]; 3-D: the tilt of the body's vertical
    axis from its initial direction [rad])."""

    name: str
    body: int
    field: str
    axis: int = 0

    def __check_init__(self):
        fields = (
            "centre",
            "velocity",
            "force",
            "contact_force",
            "friction",
            "impulse",
            "angular_velocity",
            "torque",
            "angular_impulse",
            "angle",
        )
        if self.field not in fields:
            raise ValueError(f"BodyValue.field must be one of {fields}.")

    def __call__(self, scene: Scene, state: State):
        rigid = state.rigid
        if self.field == "angle":
            q = rigid.orientation[self.body]
            if scene.dim == 2:
                return q[0]
            # cos(tilt) = R_zz = 1 - 2 (x^2 + y^2)
            c = 1.0 - 2.0 * (q[1] ** 2 + q[2] ** 2)
            return jnp.arccos(jnp.clip(c, -1.0, 1.0))
        value = getattr(rigid, self.field)[self.body]
        return value[self.axis]


class BodyPressure(AbstractProbe):
    """Pressure [Pa] of the water on a face of rigid body `body`, at a gauge of
    radius `radius` [m] around `point` on the face, with outward unit `normal`
    (both in the body's frame: offsets from its centre, as
    `State.rigid.reference`); a pressure tap on a hull. 0 where no water touches
    the gauge.

    The water's pressure is fitted linearly against the distance from the face
    over the fluid particles within 2 l0 of it (two layers) and read at the face.
    The body's own particles are not used: their centres lie l0/2 inside the
    face, and what they carry depends on the scheme. Measured on a floating box at
    rest (validation/floating_pressure.py, B/20): with the default gradient (the
    minimum-pressure shift) its bottom row reads 4 % above the water's value at its
    centres (the box, pressed like the fluid it replaces, is solved as a fluid of
    lighter density), with the corrected gradient (`standard_ds`,
    `high_accuracy`) within 0.1 % of it, while the water extrapolated to the face
    reads rho g times the draft within 1.4 % in all three. Like every pressure it
    is noisy from step to step (35-46 % there): average over every step, not a
    few dozen samples. With the explicit solver the water's pressure alternates
    by layer (its equation of state's packing): read it a few l0 away instead
    (`FluidPressureNear`).
    """

    name: str
    body: int
    point: tuple[float, ...]
    normal: tuple[float, ...]
    spacing: float
    radius: float

    def __call__(self, scene: Scene, state: State):
        dtype = state.position.dtype
        rigid = state.rigid
        turn = rotation_matrix(rigid.orientation[self.body], scene.dim)
        n = matmul(turn, jnp.asarray(self.normal, dtype))
        n = n / jnp.linalg.norm(n)
        face = rigid.centre[self.body] + matmul(turn, jnp.asarray(self.point, dtype))
        offset = state.position - face[None, :]
        h = matmul(offset, n)  # distance out of the face
        along = offset - h[:, None] * n[None, :]
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        near = fluid & (h > 0.0) & (h <= 2.0 * self.spacing)
        near = near & (jnp.sum(along * along, axis=-1) <= self.radius**2)
        w = near.astype(dtype)
        h = jnp.where(near, h, 0.0)
        p = jnp.where(near, state.pressure, 0.0)
        s1, sh, shh = jnp.sum(w), jnp.sum(h), jnp.sum(h * h)
        sp, shp = jnp.sum(p), jnp.sum(h * p)
        spread = s1 * shh - sh**2
        fitted = spread > 0.01 * self.spacing**2 * s1**2
        slope = jnp.where(
            fitted, (s1 * shp - sh * sp) / jnp.where(fitted, spread, 1.0), 0.0
        )
        return jnp.where(s1 > 0, (sp - slope * sh) / jnp.maximum(s1, 1.0), 0.0)


class BodiesMoved(AbstractProbe):
    """How many rigid bodies lie farther than `distance` [m] from where they
    started (`start`: their centres then, shape (b, d)); a block counts as
    washed out once it has left its place by more than its own length."""

    name: str
    start: Float[Array, "b d"] = eqx.field(converter=jnp.asarray)
    distance: float

    def __call__(self, scene: Scene, state: State):
        step = state.rigid.centre - self.start
        squared = sum(step[:, k] ** 2 for k in range(step.shape[-1]))
        return jnp.sum(squared > self.distance**2).astype(step.dtype)


class BedLowering(AbstractProbe):
    """The scour hole in a bed of DEM grains: its deepest lowering below the bed's
    first surface (`measure` "depth") or its length ("length") [m].

    The bed over [x0, x0 + bins width) is cut into `bins` of `width`; a bin's
    surface is the top (centre + d/2) of its highest grain in the bed (attached,
    or resting on at least two partners: not one carried over it), or the pit's
    `floor` where it has none. The first surface is the same of every grain's
    place (`GrainState.origin`: where it lay at `GrainParams.release_time`, so
    that the bed's settling before it is not read as scour). The hole is the
    run of bins lowered by more than one `diameter` round the deepest one."""

    name: str
    bins: int
    measure: str
    x0: float
    width: float
    floor: float
    diameter: float

    def __check_init__(self):
        if self.measure not in ("depth", "length"):
            raise ValueError('BedLowering.measure must be "depth" or "length".')

    @staticmethod
    def surface_of(position, in_bed, bins: int, *, x0, width, floor, diameter, xp=np):
        """Each bin's bed surface from grain centres `position` (m, d) and which
        of them lie in the bed (`in_bed`)."""
        b = xp.floor((position[:, 0] - x0) / width).astype(xp.int32)
        inside = in_bed & (b >= 0) & (b < bins)
        top = xp.where(inside, position[:, -1] + 0.5 * diameter, floor)
        b = xp.clip(b, 0, bins - 1)
        if xp is np:
            surface = np.full(bins, floor, dtype=float)
            np.maximum.at(surface, b, top)
            return surface
        return jnp.full(bins, floor, top.dtype).at[b].max(top)

    def __call__(self, scene: Scene, state: State):
        del scene
        gs = state.grains
        in_bed = gs.attached | (gs.contact_count >= 2)
        bins = self.bins
        where = {
            "x0": self.x0,
            "width": self.width,
            "floor": self.floor,
            "diameter": self.diameter,
            "xp": jnp,
        }
        surface = self.surface_of(state.position[gs.index], in_bed, bins, **where)
        first = self.surface_of(gs.origin, jnp.ones_like(in_bed), bins, **where)
        lowered = first - surface
        deepest = jnp.argmax(lowered)
        depth = lowered[deepest]
        if self.measure == "depth":
            return jnp.maximum(depth, 0.0)
        k = jnp.arange(bins)
        shallow = lowered <= self.diameter
        start = jnp.max(jnp.where(shallow & (k < deepest), k, -1)) + 1
        end = jnp.min(jnp.where(shallow & (k > deepest), k, bins))
        return jnp.where(depth > self.diameter, (end - start) * self.width, 0.0)


def _walls_in_box(state: State, lower, upper):
    """The active pressure-wall particles inside the box [lower, upper]."""
    x = state.position
    low = jnp.asarray(lower, x.dtype)[None, :]
    high = jnp.asarray(upper, x.dtype)[None, :]
    inside = jnp.all((x >= low) & (x <= high), axis=-1)
    return state.active & (state.kind == int(Kind.WALL)) & inside


class WallForce(AbstractProbe):
    """Force [N, or N/m in 2-D] on the pressure-wall particles inside the box
    [`lower`, `upper`]: the sum of P_i l0^(d-1) (seed 000: the collision force is the
    wall pressure integrated over the contact face) and, in scenes with bodies,
    of the magnitudes of the contact push the bodies exerted on them
    (`RigidState.wall_push`: a dry body's particles carry little pressure, and
    the push holds it off the wall; `ElasticState.wall_push` with
    `contact="push"`, which leaves those pairs out of the pressure). Positive
    into the wall. A probe
    is a function of one state: the impulse on the segment is the time integral of
    the saved history (save every step for impacts, as `block_impact`'s test does).

    `dry` is the pressure a wall particle carries with no water on it (the
    semi-implicit solver's `surface_head` rho |g| l0; 0 for the explicit solver):
    with it, each particle counts P_i - dry where that is positive, so that a dry
    face reads zero (a wetted one then reads up to dry x l0^(d-1) per particle low).
    """

    name: str
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    spacing: float
    dry: float = 0.0

    def __call__(self, scene: Scene, state: State):
        del scene
        wall = _walls_in_box(state, self.lower, self.upper)
        area = self.spacing ** (state.position.shape[-1] - 1)
        excess = (
            jnp.maximum(state.pressure - self.dry, 0.0) if self.dry else state.pressure
        )
        force = jnp.sum(jnp.where(wall, excess, 0.0)) * area
        for bodies in (state.rigid, state.elastic):
            if bodies is not None:
                force += jnp.sum(safe_norm(bodies.wall_push, wall, placeholder=0.0))
        return force


class WallPressure(AbstractProbe):
    """Mean pressure [Pa] of the pressure-wall particles inside the box [`lower`,
    `upper`] (a pressure gauge on a wall), less `dry` (see `WallForce`) and at
    least zero; zero where the box holds none."""

    name: str
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    dry: float = 0.0

    def __call__(self, scene: Scene, state: State):
        del scene
        wall = _walls_in_box(state, self.lower, self.upper)
        excess = jnp.maximum(state.pressure - self.dry, 0.0)
        return jnp.sum(jnp.where(wall, excess, 0.0)) / jnp.maximum(jnp.sum(wall), 1)


class RunUp(AbstractProbe):
    """Run-up on a slope rising 1 : `slope` from x = `toe` (tank frame): the highest
    fluid particle within `band` of the slope surface, above `still_depth` [m].
    The tank frame follows particle `anchor`, initially at x = `anchor_x`."""

    name: str
    anchor: int
    anchor_x: float
    toe: float
    slope: float
    band: float
    still_depth: float

    def __call__(self, scene: Scene, state: State):
        x = _tank_frame(state, self.anchor, self.anchor_x) - self.toe
        y = state.position[:, 1]
        gap = (y * self.slope - x) / jnp.sqrt(1.0 + self.slope**2)
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        near = fluid & (gap < self.band) & (x > 0)
        top = jnp.max(jnp.where(near, y, -jnp.inf))
        return jnp.where(jnp.isfinite(top), top - self.still_depth, 0.0)


class ModeAmplitude(AbstractProbe):
    """Amplitude [m] of the surface mode cos(k x) over a tank [0, L] with k L a
    multiple of 2 pi: a = (2/L) sum_fluid cos(k x_j) l0^2, the discrete form of
    (2/L) int int_fluid cos(k x) dA = (2/L) int eta(x) cos(k x) dx (2-D), with
    k L a multiple of pi. An integral over all particles: far smoother than a
    level at one x. With `anchor`, x is measured in the frame of that (moving)
    wall particle, initially at x = `anchor_x`. `still` is the sum's value for the
    water at rest, subtracted (nonzero where solids inside the water, a plate at
    one wall say, take part of the integral's area)."""

    name: str
    wave_number: float
    length: float
    spacing: float
    anchor: int | None = None
    anchor_x: float = 0.0
    still: float = 0.0

    def __call__(self, scene: Scene, state: State):
        fluid = jnp.logical_and(state.active, state.kind == int(Kind.FLUID))
        c = jnp.cos(self.wave_number * _tank_frame(state, self.anchor, self.anchor_x))
        total = 2.0 / self.length * jnp.sum(jnp.where(fluid, c, 0.0)) * self.spacing**2
        return total - self.still


class Displacement(AbstractProbe):
    """Mean displacement [m] of the particles `particles` along `axis` from their
    mean initial coordinate `start` (an elastic beam's tip, say), times `sign`
    (-1: counted positive towards -axis, a deflection downwards)."""

    name: str
    particles: tuple[int, ...]
    axis: int
    start: float
    sign: float = 1.0

    def __call__(self, scene: Scene, state: State):
        del scene
        index = jnp.asarray(self.particles)
        return self.sign * (jnp.mean(state.position[index, self.axis]) - self.start)


class ElasticValue(AbstractProbe):
    """The mean over an elastic body's particles of their position (`field`
    "centre") or velocity ("velocity"), or the sum of the walls' contact push on
    them in the last step ("contact_force" [N], `ElasticBodies.contact` "push"),
    component `axis`."""

    name: str
    body: int
    field: str
    axis: int = 0

    def __check_init__(self):
        if self.field not in ("centre", "velocity", "contact_force"):
            raise ValueError(
                'ElasticValue.field must be "centre", "velocity" or "contact_force".'
            )

    def __call__(self, scene: Scene, state: State):
        del scene
        es = state.elastic
        value = {
            "centre": es.position,
            "velocity": es.velocity,
            "contact_force": es.contact_force,
        }[self.field]
        member = es.body == self.body
        total = jnp.sum(jnp.where(member, value[:, self.axis], 0.0))
        if self.field == "contact_force":
            return total
        return total / jnp.maximum(jnp.sum(member), 1)


class ElasticAmplitude(AbstractProbe):
    """The largest magnitude over the elastic particles `particles` (numbers within
    the elastic sub-state) of their elastic pressure (`field` "pressure", from the
    last step) or of the normal stress 2 mu eps along `axis` ("stress", with
    `shear_modulus` mu the body's, at the state's configuration) [Pa]."""

    name: str
    particles: tuple[int, ...]
    field: str
    axis: int = 0
    shear_modulus: float = 0.0

    def __check_init__(self):
        if self.field not in ("pressure", "stress"):
            raise ValueError('ElasticAmplitude.field must be "pressure" or "stress".')

    def __call__(self, scene: Scene, state: State):
        es = state.elastic
        index = jnp.asarray(self.particles)
        if self.field == "pressure":
            return jnp.max(jnp.abs(es.elastic_pressure[index]))
        mu = jnp.full(es.index.shape, self.shear_modulus, es.position.dtype)
        disc = scene.discretisation
        stress = elastic_stress(
            disc,
            mu,
            es.reference,
            es.position,
            es.rotation,
            es.neighbours,
            corrective_matrices(disc, es.reference, es.neighbours)
            if scene.elastic.surface_correction
            else None,
        )
        return jnp.max(jnp.abs(stress[index, self.axis, self.axis]))


class GrainValue(AbstractProbe):
    """The mean over the grains `grains` (numbers within the grains' sub-state) of
    their position (`field` "position") or velocity ("velocity"), component
    `axis`."""

    name: str
    grains: tuple[int, ...]
    field: str
    axis: int = 0

    def __check_init__(self):
        if self.field not in ("position", "velocity"):
            raise ValueError('GrainValue.field must be "position" or "velocity".')

    def __call__(self, scene: Scene, state: State):
        del scene
        index = state.grains.index[jnp.asarray(self.grains)]
        value = state.position if self.field == "position" else state.velocity
        return jnp.mean(value[index, self.axis])


class GrainRunout(AbstractProbe):
    """How far a grain deposit reaches along x from `x_start` [m]: the grains
    within `band` of the floor `floor` are binned in bins of two grain diameters
    `diameter` from `x_start`; the runout is the largest x (plus d/2) in the last
    bin of the contiguous run of occupied bins, so that a grain bounced ahead
    alone does not count. (Bins of one diameter broke the run where a
    polydisperse bottom row left one without a grain centre: a deposit 3.3 L0
    long once read 0.95 L0.)"""

    name: str
    x_start: float
    floor: float
    band: float
    diameter: float
    n_bins: int

    def __call__(self, scene: Scene, state: State):
        del scene
        gs = state.grains
        x = state.position[gs.index, 0] - self.x_start
        low = state.position[gs.index, -1] < self.floor + self.band
        hit = low & (x >= 0)
        b = jnp.clip(jnp.floor(x / (2.0 * self.diameter)), 0, self.n_bins - 1)
        b = b.astype(jnp.int32)
        occupied = jnp.zeros(self.n_bins, bool).at[b].max(hit)
        run = jnp.sum(jnp.cumprod(occupied.astype(jnp.int32)))
        last = hit & (b == run - 1)
        front = jnp.max(jnp.where(last, x, -jnp.inf)) + 0.5 * self.diameter
        return jnp.where(run > 0, front, 0.0)


class GrainHeight(AbstractProbe):
    """The height above `floor` of the highest grain whose centre lies in
    [x0, x1), plus its radius [m]; zero where there is none."""

    name: str
    x0: float
    x1: float
    floor: float

    def __call__(self, scene: Scene, state: State):
        del scene
        gs = state.grains
        x = state.position[gs.index]
        inside = (x[:, 0] >= self.x0) & (x[:, 0] < self.x1)
        top = jnp.max(jnp.where(inside, x[:, -1] + 0.5 * gs.diameter, -jnp.inf))
        return jnp.where(jnp.isfinite(top), top - self.floor, 0.0)
