"""Host-side construction of DEM grains in a built case (NumPy; validates its
inputs)."""

import dataclasses
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from . import bodies
from ._build import _grid
from ._params import GrainParams, Params
from ._scene import Scene
from ._state import GrainState, State
from ._types import Kind
from .bodies import rotation as rot
from .neighbours import candidate_counts

# Choice: contact slots per grain. Within the search radius (1.4 d for grains of
# the wall particles' size) a grain of a square packing has 8 candidates in 2-D
# and 18 in 3-D, of a hexagonal one 6 and 12; the slots leave room for walls and
# a denser heap.
CONTACT_CAPACITY = {2: 16, 3: 32}
# Choice: the DEM search's candidate capacity is this margin over the most
# candidates a grain has at the start (a heap settles denser than it starts).
CANDIDATE_MARGIN = 2.0

# Kinds whose walls make grains feel bodies (`Grains.on_bodies`).
BODY_KINDS = (int(Kind.RIGID), int(Kind.ELASTIC))


def add_grains(
    scene: Scene,
    params: Params,
    state: State,
    grains,
    *,
    friction,
    restitution,
    density,
    stiffness=None,
    overlap: float = 0.02,
    speed: float | None = None,
    lift: float = 0.2,
    rolling: float = 0.0,
    diameter=None,
    contact_capacity: int | None = None,
    candidate_capacity: int | None = None,
    substeps: int | None = None,
    packed_density: float | None = None,
    courant: float = bodies.Grains.courant,
    dashpot_ramp: float = bodies.Grains.dashpot_ramp,
    on_bodies: bool = True,
    on_fluid: bool = False,
    attached=None,
    detach_distance: float = bodies.Grains.detach_distance,
    junction_correction: bool | None = None,
    release_time: float | None = None,
) -> tuple[Scene, Params, State]:
    """Turn particles of a built case into DEM grains (seed 002 §5): spheres of
    one particle each (`Kind.SEDIMENT`), in contact with one another and with the
    case's wall particles and the particles of its rigid and elastic bodies
    (which feel them back), hidden from the fluid, which drags and lifts them
    (`jaxmps.bodies.Grains`). Add the bodies first.

    Args:
        scene, params, state: a case (from `make_scene` etc.).
        grains: which particles become grains: a boolean per initial particle
            (or per slot); they must be active and not yet bodies or walls.
        friction: the Coulomb friction coefficient mu of grain contacts.
        restitution: the normal coefficient of restitution e, in (0, 1].
        density: the grains' material density rho_s [kg/m^3]; in a case with
            fluid it must exceed the fluid's (the grains are advanced with their
            submerged density rho_s - rho_w, seed 002 §5.1).
        stiffness: the normal contact stiffness k_n [N/m]; None: the stiffness
            at which the heaviest grain, meeting a wall at `speed`, overlaps it
            by `overlap` of its diameter: k_n = m (speed / (overlap d))^2;
            "rule": seed 002's rule (pi^2 / 200) m / dt^2 of the lightest grain
            at `Params.dt` (`bodies.rule_stiffness`: one DEM sub-step per
            step; soft at a semi-implicit step).
        overlap: that overlap, as a share of the diameter (0.02).
        speed: that speed [m/s]; None: the free-fall speed sqrt(2 g H) over the
            height H spanned by the grains and the fluid.
        lift: the lift coefficient C_L (seed 002: 0.2).
        rolling: the rolling resistance coefficient mu_r (seed 002: none, 0).
        diameter: the grains' diameter [m], a scalar or one per grain; None: the
            scene's spacing l0 (seed 002 §2.10: one size for all particles).
        contact_capacity: contact slots per grain (default `CONTACT_CAPACITY`).
        candidate_capacity: the most grains and walls the contact search's cells
            around one grain may hold (default: `CANDIDATE_MARGIN` times the most
            at the start).
        substeps: DEM sub-steps per step; None: the fewest that keep a sub-step
            within seed 002's rule step at `Params.dt` (`bodies.rule_step`).
        packed_density: n_s0, the solid number density of a packed bed (the
            velocity correction of seed 002 eq. 3.80 and the junction
            correction of eq. 3.73); None: with attached grains, the largest
            number density an attached grain has among the grains and walls
            at the start (a bed a few grains deep has grains of full support),
            else the scene's n0 (a bed on the fluid's lattice).
        courant: a step moves a grain by at most courant l0 (`Grains.courant`).
        dashpot_ramp: the share of the contact distance over which the dashpots
            engage (0: at once, as seed 002; a calibration by gradient may want
            a smooth onset, `Grains.dashpot_ramp`).
        on_bodies: whether the rigid and elastic bodies the grains touch feel
            their contact forces (True: blocks rest on grains; False: seed
            002's detached grains, which do not act on blocks).
        on_fluid: whether the fluid feels the grains' drag and lift back
            (False: seed 002, "no reaction on the fluid"; True keeps the
            momentum of fluid and grains together, see `Grains`).
        attached: which of the grains start in the bed (a boolean per initial
            particle, as `grains`; None: none): walls to the fluid and the
            bodies, their pairs weighing n0 / n_s0 in the fluid's sums (seed
            002 §5.5 and eq. 3.73), moved by the DEM all the same, until one
            has moved `detach_distance` diameters from its start and is free
            for good.
        detach_distance: that distance, in diameters (`Grains.detach_distance`;
            seed 002 gives no criterion).
        junction_correction: whether the attached grains' pairs weigh
            n0 / n_s0 (seed 002 eq. 3.73); None: yes, but with the explicit
            solver's `wall_pressure="facing"`, whose walls take the fluid's
            pressure whatever their own number density (measured:
            validation/bed_junction.py).
        release_time: the grains feel no fluid force until then [s], settling
            into the bed under their own weight while the flow spins up
            (`Params.grains.release_time`; seed 002's spin-up with the grains
            fixed); None: from the start.

    Returns:
        The new (scene, params, state).

    Raises:
        ValueError: for a mask that selects no particle or an inactive, wall or
            body particle; friction < 0; restitution outside (0, 1]; density or
            stiffness not positive (or, in water, not above the fluid's
            density); grains that overlap at the start; grains in water larger
            than r_e; a `substeps` that leaves `Params.dt` beyond the grains'
            contact limit.
    """
    if scene.grains is not None:
        raise ValueError("This scene already has grains; add all in one call.")
    selected, index, sizes, fluid = _grain_particles(
        scene, state, grains, diameter, on_fluid
    )
    position = np.asarray(state.position, np.float64)
    kind = np.array(state.kind)
    active = np.asarray(state.active)
    submerged = bool(np.any(fluid))
    values = {
        "friction": friction,
        "restitution": restitution,
        "density": density,
        "stiffness": stiffness,
        "lift": lift,
        "rolling": rolling,
        "release_time": release_time,
    }
    grain_params = _material(
        params, values, position, selected | fluid, sizes, submerged, overlap, speed
    )
    _refuse_overlaps(position[index], sizes)
    if submerged:
        _refuse_large(sizes, scene.r_e)
    walls, grid, radius = _contact_search(
        scene, position, active, kind, index, sizes, courant, candidate_capacity
    )
    bed = _attached(attached, selected, index)
    if packed_density is None:
        packed_density = _default_packing(scene, position, active, kind, index[bed])
    model = _grains_model(
        scene,
        params,
        grain_params,
        sizes,
        submerged,
        grid,
        radius,
        on_bodies=bool(on_bodies) and bool(np.isin(kind[walls], BODY_KINDS).any()),
        bed=bed,
        packed_density=packed_density,
        contact_capacity=contact_capacity,
        substeps=substeps,
        on_fluid=on_fluid,
        detach_distance=detach_distance,
        junction_correction=junction_correction,
        courant=courant,
        dashpot_ramp=dashpot_ramp,
    )
    return _with_grains(
        scene, params, state, model, grain_params, index, walls, sizes, bed
    )


def _grain_particles(scene: Scene, state: State, grains, diameter, on_fluid):
    """The particles `add_grains` turns into grains: their mask over the slots,
    their indices, their diameters, and the mask of the fluid left around them
    (`on_fluid` refused where there is none)."""
    selected = _selected(grains, scene.capacity, state)
    index = np.nonzero(selected)[0]
    sizes = _diameters(diameter, len(index), scene.spacing)
    kind, active = np.asarray(state.kind), np.asarray(state.active)
    fluid = active & (kind == int(Kind.FLUID)) & ~selected
    if on_fluid and not np.any(fluid):
        raise ValueError(
            "on_fluid=True (scene setting on_fluid) asks the fluid to feel the "
            "grains' drag, but this case has no fluid: leave on_fluid=False."
        )
    return selected, index, sizes, fluid


def _default_packing(scene: Scene, position, active, kind, bed_index) -> float:
    """n_s0 where `packed_density` is not given: the bed's largest number density
    with attached grains, the scene's n0 without."""
    if len(bed_index) == 0:
        return scene.n0
    return _bed_density(scene, position, active, kind, bed_index)


def _grains_model(
    scene,
    params,
    grain_params,
    sizes,
    submerged,
    grid,
    radius,
    *,
    on_bodies,
    bed,
    packed_density,
    contact_capacity,
    substeps,
    on_fluid,
    detach_distance,
    junction_correction,
    courant,
    dashpot_ramp,
) -> bodies.Grains:
    """The grains' static model from `add_grains`' settings."""
    return bodies.Grains(
        count=len(sizes),
        spacing=scene.spacing,
        grid=grid,
        search_radius=radius,
        contact_capacity=CONTACT_CAPACITY[scene.dim]
        if contact_capacity is None
        else int(contact_capacity),
        substeps=_substeps(params, grain_params, sizes, submerged, substeps),
        submerged=submerged,
        on_bodies=on_bodies,
        on_fluid=bool(on_fluid),
        bed=bool(bed.any()),
        detach_distance=float(detach_distance),
        packing=_packing(scene, packed_density, bed, junction_correction),
        packed_density=float(packed_density),
        courant=float(courant),
        dashpot_ramp=float(dashpot_ramp),
    )


def _with_grains(scene, params, state, model, grain_params, index, walls, sizes, bed):
    """The case with `model`'s grains in it: the particles `index` become grains
    (those of the bed walls until detached), checked as a rollout would check
    them."""
    sub = _grain_state(scene, state, model, index, walls, sizes, bed)
    kind = np.array(state.kind)
    kind[index] = np.where(bed, int(Kind.WALL), int(Kind.SEDIMENT))
    new_params = dataclasses.replace(params, grains=grain_params)
    new_state = dataclasses.replace(
        state, kind=jnp.asarray(kind, state.kind.dtype), grains=sub
    )
    model.check(new_params, new_state)
    if scene.time_step is None:
        model.check_body_step(new_params, new_state)
    return dataclasses.replace(scene, grains=model), new_params, new_state


def _material(params, values, position, mobile, sizes, submerged, overlap, speed):
    """The grains' `GrainParams` from the material settings, checked, with the
    default stiffness where none is given (`_stiffness`)."""
    _check_material(params, values, submerged)
    if isinstance(values["stiffness"], str):
        if values["stiffness"] != "rule":
            raise ValueError(
                f"stiffness={values['stiffness']!r}: give a number of N/m, 'rule' "
                "(seed 002's rule at Params.dt) or None (the overlap rule)."
            )
        values = dict(values)
        water = float(params.density) if submerged else 0.0
        mass = (float(values["density"]) - water) * bodies.sphere_volume(sizes.min())
        values["stiffness"] = bodies.rule_stiffness(mass, float(params.dt))
    if values["stiffness"] is None:
        values = dict(values)
        values["stiffness"] = _stiffness(
            params,
            position,
            mobile,
            sizes,
            values["density"],
            submerged,
            overlap,
            speed,
        )
    return _grain_params(params, values)


def _substeps(params: Params, grain_params, sizes, submerged: bool, substeps):
    """The DEM sub-steps per step: `substeps`, or the fewest that keep a sub-step
    within seed 002's rule step of the lightest grain at `Params.dt`."""
    if substeps is not None:
        return int(substeps)
    water = float(params.density) if submerged else 0.0
    mass = (float(grain_params.density) - water) * bodies.sphere_volume(sizes)
    step = bodies.rule_step(mass.min(), float(grain_params.stiffness))
    return max(1, math.ceil(float(params.dt) / step * (1 - 1e-9)))


def _grain_state(scene: Scene, state: State, model, index, walls, sizes, bed):
    """The grains' sub-state at the start: no contacts, no spin, nothing pushed
    yet, the bed's grains attached where they lie."""
    m, k, dim = model.count, model.contact_capacity, scene.dim
    dtype = state.position.dtype
    return GrainState(
        index=jnp.asarray(index, jnp.int32),
        walls=jnp.asarray(walls, jnp.int32),
        diameter=jnp.asarray(sizes, dtype),
        partner=jnp.full((m, k), m + len(walls), jnp.int32),
        shear=jnp.zeros((dim, m, k), dtype),
        spin=jnp.zeros((m, rot.spin_size(dim)), dtype),
        fluid_force=jnp.zeros((m, dim), dtype),
        contact_count=jnp.zeros((m,), jnp.int32),
        reaction=jnp.zeros((scene.capacity if model.reacts else 0, dim), dtype),
        attached=jnp.asarray(bed),
        origin=jnp.asarray(state.position)[index],
    )


def _attached(attached, selected: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Per grain, whether it starts in the bed; refuses a mask that selects
    particles that are not grains."""
    if attached is None:
        return np.zeros(len(index), bool)
    mask = np.asarray(attached)
    if mask.ndim != 1 or mask.dtype != bool or mask.shape[0] > selected.shape[0]:
        raise ValueError(
            "attached must be a 1-D boolean array like grains, got shape "
            f"{mask.shape} and dtype {mask.dtype}."
        )
    full = np.zeros(selected.shape[0], bool)
    full[: mask.shape[0]] = mask
    if np.any(full & ~selected):
        raise ValueError(
            "attached selects particles that are not grains; it must be a part of "
            "the grains mask."
        )
    return full[index]


def _packing(scene: Scene, packed_density, bed, correction) -> float:
    """The weight of an attached grain's pairs in the fluid's sums: n0 / n_s0
    with the junction correction, 1 without (or without a bed)."""
    if correction is None:
        correction = getattr(scene.solver, "wall_pressure", None) != "facing"
    if not bed.any() or not correction:
        return 1.0
    return float(scene.n0 / packed_density)


def _bed_density(scene: Scene, position, active, kind, bed: np.ndarray) -> float:
    """n_s0: the largest number density (the fluid's weight and r_e) of an
    attached grain among the grains of the bed and the walls."""
    solid = active & np.isin(kind, [int(Kind.WALL), int(Kind.DUMMY)])
    solid[bed] = True
    others = position[solid]
    weight = scene.discretisation.weight
    best = 0.0
    for i in bed:
        r = np.linalg.norm(others - position[i], axis=1)
        near = (r > 0) & (r < scene.r_e)
        rs = jnp.asarray(r[near])
        value = np.asarray(weight(rs, jnp.ones(rs.shape, bool), scene.r_e))
        best = max(best, float(value.sum()))
    return best


def _refuse_large(sizes: np.ndarray, r_e: float) -> None:
    """Grains in water must be at most r_e across (ValueError)."""
    if sizes.max() > r_e:
        raise ValueError(
            f"A grain of {sizes.max():g} m is larger than the fluid's influence "
            f"radius r_e = {r_e:g} m: the drag takes the fluid velocity around "
            "a grain from its neighbours within r_e, a point-particle model. Give "
            "grains at most r_e across (`diameter`, scene setting `grain_diameter`), "
            "or a coarser fluid (a larger `spacing`)."
        )


def _contact_search(
    scene, position, active, kind, index, sizes, courant, candidate_capacity
):
    """The grains' contact partners that are not grains (slots), their search
    grid (with its candidate capacity) and search radius."""
    l0 = scene.spacing
    # Choice: grains touch every solid particle that is not a grain (walls, and
    # rigid and elastic bodies as spheres of l0 moving with them). Seed 002's
    # detached grains "do not affect the fluid or the rigid bodies", its blocks
    # rest on attached grains acting as walls; here the bodies feel the grains'
    # contacts (`add_grains(on_bodies=True)`), so that they rest on a bed.
    solid = (Kind.WALL, Kind.RIGID, Kind.ELASTIC)
    walls = np.nonzero(active & np.isin(kind, [int(k) for k in solid]))[0]
    skin = 2.0 * courant * l0
    reach = 0.5 * (sizes.max() + max(sizes.max(), l0))
    radius = float(reach + skin)
    grid = _grid(position[active], _domain(scene), radius, 1)
    dem = np.concatenate([position[index], position[walls]])
    if candidate_capacity is None:
        most = int(candidate_counts(grid, dem).max())
        candidate_capacity = max(4, math.ceil(CANDIDATE_MARGIN * most))
    grid = eqx.tree_at(lambda g: g.candidate_capacity, grid, int(candidate_capacity))
    return walls, grid, radius


def _selected(grains, capacity: int, state: State) -> np.ndarray:
    """The grain mask per slot; refuses an empty one and slots that are not
    active fluid (or plain) particles."""
    mask = np.asarray(grains)
    if mask.ndim != 1 or mask.dtype != bool or mask.shape[0] > capacity:
        raise ValueError(
            f"grains must be a 1-D boolean array of at most {capacity} entries, got "
            f"shape {mask.shape} and dtype {mask.dtype}."
        )
    selected = np.zeros(capacity, bool)
    selected[: mask.shape[0]] = mask
    if not selected.any():
        raise ValueError("grains selects no particle; give a mask with some True.")
    kind = np.asarray(state.kind)
    if np.any(selected & ~np.asarray(state.active)):
        raise ValueError("grains selects inactive slots (the pool); select particles.")
    if np.any(selected & (kind != int(Kind.FLUID))):
        raise ValueError(
            "grains selects wall, dummy or body particles; grains are made of "
            "plain particles (Kind.FLUID before this call)."
        )
    return selected


def _diameters(diameter, m: int, l0: float) -> np.ndarray:
    """Each grain's diameter: l0, one value, or one per grain (positive, finite)."""
    if diameter is None:
        return np.full(m, l0)
    sizes = np.asarray(diameter, np.float64)
    if sizes.ndim == 0:
        sizes = np.full(m, float(sizes))
    if sizes.shape != (m,):
        raise ValueError(
            f"diameter must be a scalar or one value per grain ({m}), got shape "
            f"{sizes.shape}."
        )
    if not np.all(np.isfinite(sizes) & (sizes > 0)):
        raise ValueError(f"diameter must be positive and finite, got {sizes.min()}.")
    return sizes


def _stiffness(
    params: Params, position, mobile, sizes, density, submerged, overlap, speed
) -> float:
    """k_n = m (speed / (overlap d))^2 for the heaviest grain (`add_grains`).

    Choice: not seed 002's rule (pi^2 / 200) m / dt^2 (`bodies.rule_stiffness`),
    which ties the stiffness to the fluid's step: the seed's explicit steps of
    5e-5 s make it stiff, but a semi-implicit step of 1e-3 s makes it 400 times
    softer, and a 5-grain column dropped by 5 cm onto a wall (l0 = 1 cm) then
    sank a diameter into it. The step follows the stiffness instead, by DEM
    sub-steps (`substeps`)."""
    if not 0 < overlap < 1:
        raise ValueError(f"overlap must lie in (0, 1), got {overlap!r}.")
    if speed is None:
        g = float(np.linalg.norm(np.asarray(params.gravity, np.float64)))
        height = np.ptp(position[mobile, -1]) if np.any(mobile) else 0.0
        speed = math.sqrt(2.0 * g * max(height, float(sizes.max())))
    if not speed > 0:
        raise ValueError(
            "no speed to derive the grains' stiffness from (no gravity): give "
            "`stiffness` (N/m) or `speed` (m/s)."
        )
    rho = float(density) - (float(params.density) if submerged else 0.0)
    heaviest = rho * bodies.sphere_volume(float(sizes.max()))
    return heaviest * (speed / (overlap * float(sizes.max()))) ** 2


def _check_material(params: Params, values: dict, submerged: bool) -> None:
    """One number per material setting, and grains denser than the fluid they
    lie in (ValueError by name); the ranges are `GrainParams`'."""
    for name, value in values.items():
        if value is not None and np.ndim(value) != 0:
            raise ValueError(
                f"{name} must be one number for all grains, got {value!r}."
            )
    rho_w, density = float(params.density), float(values["density"])
    if submerged and not density > rho_w:
        raise ValueError(
            f"density={density:g} kg/m^3 is not above the fluid's {rho_w:g}: "
            "grains in water are advanced with their submerged weight (seed 002 "
            "§5.1), and a grain that floats is not modelled. Give a denser grain "
            "(scene setting `grain_density`)."
        )


def _grain_params(params: Params, values: dict) -> GrainParams:
    """The grains' Params in the dtype of `params` (`GrainParams` checks the
    ranges by name)."""
    dtype = params.density.dtype
    return GrainParams(
        **{k: jnp.asarray(v, dtype) for k, v in values.items() if v is not None}
    )


def _refuse_overlaps(position: np.ndarray, sizes: np.ndarray) -> None:
    """Refuse grains that overlap by more than 1 % of their contact distance at
    the start (their springs would fire them apart)."""
    m = len(position)
    if m < 2:
        return
    # Cells of the largest diameter: overlapping pairs lie in neighbouring cells.
    cell = sizes.max()
    keys = np.floor(position / cell).astype(np.int64)
    order = np.lexsort(keys.T[::-1])
    buckets: dict[tuple, list[int]] = {}
    for i in order:
        buckets.setdefault(tuple(keys[i]), []).append(i)
    dim = position.shape[1]
    offsets = np.array(np.meshgrid(*[[-1, 0, 1]] * dim)).reshape(dim, -1).T
    for key, members in buckets.items():
        near = [j for off in offsets for j in buckets.get(tuple(np.add(key, off)), [])]
        near = np.asarray(near)
        for i in members:
            others = near[near != i]
            if not len(others):
                continue
            gap = np.linalg.norm(position[others] - position[i], axis=1)
            reach = 0.5 * (sizes[i] + sizes[others])
            if np.any(gap < 0.99 * reach):
                j = int(others[np.argmin(gap - reach)])
                raise ValueError(
                    f"Grains {int(i)} and {j} overlap at the start (centres "
                    f"{gap.min():.3g} m apart, contact at {reach.min():.3g} m): "
                    "place grains at least a diameter apart."
                )


def _domain(scene: Scene):
    """The scene's domain box (its neighbour grid's)."""
    grid = scene.grid
    return np.asarray(grid.origin), np.asarray(grid.upper)
