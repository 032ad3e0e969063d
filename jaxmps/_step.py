"""One time step: the stage pipeline, in the order of the algorithm.

    stage        what                                       done by
    boundaries   move walls, feed the inflow                fluid.move_walls,
                                                            fluid.apply_inflow
    coupling     what the body models impose on the fluid   <model>.coupling
                 (and which particles it does not see)
    neighbours   lists at r^k (carried, or searched)        neighbours.search
    predict      u* = u^k + dt (nu lap u + g)               fluid.predict
    porous       resistance in porous damping regions,      fluid.damp
                 on u^k, added to u*
    collide      collision guard on u*                      Scene.collision
    advect       r* = r^k + dt u*                           fluid.advect
    <name>       a body model's internal forces in u*, r*   <model>.predict
    neighbours   lists at r* (the same carried ones, or     neighbours.search
                 searched)
    surface      free-surface flags at r*                   fluid.detect_surface
    pressure     PPE (semi-implicit) or equation of state   Scene.solver
    correct      pressure force (body, contact parts),      fluid.pressure_force,
                 u' = -dt/rho grad P                        fluid.accelerate
    stabilise    dynamic stabilisation of u'                Scene.stabiliser
    outflow      retire outflowing fluid (and grains)       fluid.apply_outflow
    <name>       each body model advances its bodies        <model>.advance
    result       stability checks, first failure wins       _record

Each stage runs in a `jax.named_scope` of its name; a body model's is its `name`
("rigid"). A stage whose component the Scene does not have (no motion, no bodies,
...) is skipped in Python at trace time, so a scene compiles only the physics it
contains.
A new body model is an `AbstractBodyModel` under `bodies/`, one more field of
Scene/Params/State, and one entry in `Scene.body_fields`.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from . import fluid, neighbours, operators
from ._checks import check_compatible
from ._coupling import Coupling, source_view, visible
from ._numerics import finite_rows, last_axis_dot
from ._params import Params
from ._result import Result, StepInfo, update_result
from ._scene import Scene
from ._state import State
from ._types import Field, Kind, Kinds, Mask, Positions, Scalar, Velocities


def _step(
    scene: Scene,
    params: Params,
    state: State,
    batch_axis: str | None = None,
    dt: Scalar | None = None,
    counted: Mask | None = None,
) -> tuple[State, StepInfo]:
    """One step of `dt` (None: `params.dt`). `params.dt` stays the largest step
    (the body stages' reference: an elastic sub-step is a share of it);
    `params.relaxation_step`, or where it is None `params.dt`, is the pressure
    source's (`PressureInputs.reference_dt`); the stages see `params` with `dt` in
    it. `counted` (None: all): the particles whose outcome the step judges
    (`_judged`: a slab of `simulate_slabs` steps its halo's copies too)."""
    reference_dt = params.dt
    relaxation_dt = (
        params.dt if params.relaxation_step is None else params.relaxation_step
    )
    if dt is not None:
        params = eqx.tree_at(lambda p: p.dt, params, dt)
    disc, dt = scene.discretisation, params.dt
    with jax.named_scope("boundaries"):
        state, pool_short = _boundaries(scene, params, state)
    with jax.named_scope("coupling"):
        coupling = _coupling(scene, params, state)
    kind, active = state.kind, state.active
    mobile = fluid.is_mobile(kind, active)

    with jax.named_scope("neighbours"):
        nbrs_k, pairs_k, cache = _neighbours(
            scene, state.position, active, coupling, state.neighbours, batch_axis
        )
    with jax.named_scope("predict"):
        u_star = fluid.predict(disc, scene.laplacian, params, state, pairs_k, coupling)
    u_star = _with_porous(scene, params, state, u_star)
    u_forced = u_star
    if scene.collision is not None:
        with jax.named_scope("collide"):
            u_star = scene.collision(disc, u_star, kind, active, pairs_k)
    with jax.named_scope("advect"):
        x_star = fluid.advect(dt, state.position, u_star, mobile)
    for model in scene.body_models:
        with jax.named_scope(model.name):
            state, u_star, x_star = model.predict(
                disc, params, state, u_star, x_star, reference_dt, pairs=pairs_k
            )

    with jax.named_scope("neighbours"):
        nbrs, pairs, cache = _neighbours(
            scene, x_star, active, coupling, cache, batch_axis
        )
    # The density a deformable body's particles have unstrained stands for their
    # own body's pairs (`Coupling.source_view`): the surface and the pressure's
    # source see the body rigid within itself.
    n_star = source_view(coupling, pairs)[1]
    with jax.named_scope("surface"):
        surface = _surface(scene, params, n_star, kind, active, pairs, coupling)
    with jax.named_scope("pressure"):
        inputs = _pressure_inputs(
            state,
            pairs_k,
            pairs,
            n_star,
            surface,
            x_star,
            u_star,
            relaxation_dt,
            coupling,
        )
        solution = scene.solver(disc, scene.laplacian, scene.grid, params, inputs)
    with jax.named_scope("correct"):
        load = fluid.pressure_force(
            scene.gradient, disc, pairs, solution.pressure, kind, active, coupling
        )
        density = params.density if coupling is None else coupling.density
        u_prime = fluid.accelerate(dt, load.gradient, density, mobile)
    if scene.stabiliser is not None:
        with jax.named_scope("stabilise"):
            x_new = x_star + dt * u_prime
            push = scene.stabiliser(
                disc, pairs, state.position, x_new, kind, active, dt
            )
            u_prime = u_prime + dt * push
    new = _advanced(state, dt, x_star, u_star, u_prime, solution.pressure, cache)
    if scene.outflow is not None:
        with jax.named_scope("outflow"):
            new = fluid.apply_outflow(scene.outflow, scene.grid, new)
    for model in scene.body_models:
        with jax.named_scope(model.name):
            new = model.advance(disc, params, new, load)

    with jax.named_scope("result"):
        searches = (nbrs_k, nbrs)
        args = (new, solution, searches, pool_short, mobile, u_forced, counted)
        return _judged(scene, params, state, *args)


def _judged(
    scene: Scene,
    params: Params,
    state: State,
    new: State,
    solution: fluid.PressureSolution,
    searches: tuple[neighbours.Neighbours, neighbours.Neighbours],
    pool_short: Bool[Array, ""],
    mobile: Mask,
    u_forced: Velocities,
    counted: Mask | None,
) -> tuple[State, StepInfo]:
    """The step's diagnostics, the escaped fluid taken out and the first failure
    recorded, judged on the `counted` particles (None: all)."""
    nbrs_k, nbrs = searches
    info = _info(solution, nbrs_k, nbrs)
    outside = nbrs_k.outside | nbrs.outside
    mobile = mobile & new.active
    if counted is not None:
        outside, mobile = outside & counted, mobile & counted
    new, info = _take_out_escaped(scene, new, info, outside)
    forced = new.velocity if scene.solver.pressure_is_force else u_forced
    # A particle the forces carry beyond its neighbourhood (r_e) in one step
    # makes the step meaningless, whatever velocity it ends with: the searches
    # of that step overflow, or lose the particle, and would name those instead.
    speed = jnp.sqrt(last_axis_dot(forced, forced))
    too_far = jnp.max(jnp.where(mobile, speed, 0.0)) * params.dt > scene.r_e
    info = dataclasses.replace(info, unstable=info.unstable | too_far)
    accel = (forced - state.velocity) / params.dt
    new = _record(scene, params, new, info, pool_short, mobile, accel, counted)
    return new, info


def _boundaries(
    scene: Scene, params: Params, state: State
) -> tuple[State, Bool[Array, ""]]:
    """Moving walls and the inflow: the state and whether the inflow's pool ran
    short."""
    pool_short = jnp.asarray(False)
    if scene.motion is not None:
        state = fluid.move_walls(scene.motion, params.motion, params.dt, state)
    if scene.inflow is not None:
        state, pool_short = fluid.apply_inflow(
            scene.discretisation,
            scene.inflow,
            params.inflow,
            scene.grid,
            params.dt,
            state,
            # an absorbing inflow reads the depth in front against gravity
            jnp.linalg.norm(params.gravity) if scene.inflow.absorbing else None,
        )
    return state, pool_short


def _with_porous(
    scene: Scene, params: Params, state: State, u_star: Velocities
) -> Velocities:
    """u* with the porous regions' resistance on u^k (`_porous`), in the stage
    `porous`; unchanged in a scene without regions."""
    if scene.porous is None:
        return u_star
    with jax.named_scope("porous"):
        return u_star + _porous(scene, params, state) - state.velocity


def _porous(scene: Scene, params: Params, state: State) -> Velocities:
    """u^k after the porous regions' resistance over the step, on the particles in
    them at r^k; regions fixed to shaken walls move with them and damp the
    velocity relative to theirs."""
    shift, frame_velocity = _region_frame(scene, params, state)
    return fluid.damp(
        scene.porous,
        params.porous.kappa,
        params.porous.drag,
        params.dt,
        shift,
        frame_velocity,
        state.position,
        state.velocity,
        state.kind,
        state.active,
    )


def _region_frame(
    scene: Scene, params: Params, state: State
) -> tuple[Float[Array, " d"], Float[Array, " d"]]:
    """The porous regions' displacement since the start and their velocity over
    the step: the walls' where the regions move with them (a shaken tank), zero
    otherwise."""
    dim, dtype = scene.dim, state.position.dtype
    shift = jnp.zeros((dim,), dtype)
    frame_velocity = jnp.zeros((dim,), dtype)
    if scene.porous.moving:
        motion, dt = scene.motion, params.dt
        axis = jnp.asarray(motion.axis, dtype)
        now = motion.law.displacement(params.motion, state.time)
        later = motion.law.displacement(params.motion, state.time + dt)
        start = motion.law.displacement(params.motion, jnp.zeros_like(state.time))
        shift = (now - start) * axis
        frame_velocity = (later - now) / dt * axis
    return shift, frame_velocity


def _surface(
    scene: Scene,
    params: Params,
    n_star: Field,
    kind: Kinds,
    active: Mask,
    pairs: operators.Pairs,
    coupling: Coupling | None,
) -> Mask:
    """The free-surface flags at r* (none without a `Scene.surface` model); a
    porous region's neighbours count by their pore weight."""
    if scene.surface is None:
        return jnp.zeros_like(active)
    pores = None if coupling is None else coupling.pores
    return fluid.detect_surface(
        scene.surface,
        params.beta,
        scene.discretisation.n0,
        n_star,
        kind,
        active,
        pairs,
        pores,
    )


def _coupling(scene: Scene, params: Params, state: State) -> Coupling | None:
    """What the body models and porous regions with a porosity impose on the
    fluid (None in a scene without either). Each model owns its particles; their
    records are merged slot by slot."""
    disc = scene.discretisation
    parts = [model.coupling(disc, params, state) for model in scene.body_models]
    if scene.porous is not None and scene.porous.porous:
        parts.append(_pores(scene, params, state))
    if not parts:
        return None
    merged = parts[0]
    for part in parts[1:]:
        merged = Coupling(
            density=jnp.where(part.owned, part.density, merged.density),
            owner=jnp.where(part.owned, part.owner, merged.owner),
            as_fluid=jnp.where(part.owned, part.as_fluid, merged.as_fluid),
            reference_density=_merged_reference(merged, part),
            hidden=_merged_hidden(merged, part),
            packing=_merged_packing(merged, part),
            pores=_merged_pores(merged, part),
            force=_merged_force(merged, part),
            apart=_merged_apart(merged, part),
            between_bodies=merged.between_bodies or part.between_bodies,
            pressed=merged.pressed or part.pressed,
        )
    return merged


def _pores(scene: Scene, params: Params, state: State) -> Coupling:
    """The porous regions' part of the coupling: a fluid particle at x weighs
    `fluid.pore_weight` of phi(x) in the fluid's sums (`fluid.porosity_field`),
    owning nothing."""
    shift, _ = _region_frame(scene, params, state)
    phi = fluid.porosity_field(scene.porous, shift, state.position)
    water = state.active & (state.kind == int(Kind.FLUID))
    n = state.position.shape[0]
    return Coupling(
        density=jnp.broadcast_to(params.density, (n,)).astype(phi.dtype),
        owner=jnp.full((n,), -1, jnp.int32),
        as_fluid=jnp.zeros((n,), bool),
        pores=jnp.where(water, fluid.pore_weight(scene.porous, phi), 1.0),
    )


def _merged_hidden(merged: Coupling, part: Coupling) -> Mask | None:
    """The merged `Coupling.hidden`: hidden by any model."""
    if merged.hidden is None or part.hidden is None:
        return part.hidden if merged.hidden is None else merged.hidden
    return merged.hidden | part.hidden


def _merged_packing(merged: Coupling, part: Coupling) -> Field | None:
    """The merged `Coupling.packing`: the product of the models' factors."""
    if merged.packing is None or part.packing is None:
        return part.packing if merged.packing is None else merged.packing
    return merged.packing * part.packing


def _merged_pores(merged: Coupling, part: Coupling) -> Field | None:
    """The merged `Coupling.pores` (one model sets them: the porous regions)."""
    return part.pores if merged.pores is None else merged.pores


def _merged_apart(merged: Coupling, part: Coupling) -> Int[Array, " n"] | None:
    """The merged `Coupling.apart`: a model's mark wherever it sets one."""
    if merged.apart is None or part.apart is None:
        return part.apart if merged.apart is None else merged.apart
    return jnp.where(part.apart != 0, part.apart, merged.apart)


def _merged_force(merged: Coupling, part: Coupling) -> Velocities | None:
    """The merged `Coupling.force`: the sum of the models' forces."""
    if merged.force is None or part.force is None:
        return part.force if merged.force is None else merged.force
    return merged.force + part.force


def _merged_reference(merged: Coupling, part: Coupling) -> Field | None:
    """The merged `Coupling.reference_density` (-1 where a model gives none)."""
    if merged.reference_density is None and part.reference_density is None:
        return None
    unset = jnp.full_like(part.density, -1.0)
    old = unset if merged.reference_density is None else merged.reference_density
    new = unset if part.reference_density is None else part.reference_density
    return jnp.where(part.owned, new, old)


def _neighbours(
    scene: Scene,
    position: Positions,
    active: Mask,
    coupling: Coupling | None = None,
    cache: neighbours.NeighbourCache | None = None,
    batch_axis: str | None = None,
) -> tuple[neighbours.Neighbours, operators.Pairs, neighbours.NeighbourCache | None]:
    """Neighbour lists at `position` (the carried ones while valid), their pair
    geometry as the fluid stages see it (`visible`: none with a hidden
    particle), and the lists to carry on (None without a `cache`)."""
    disc = scene.discretisation
    nbrs, cache = neighbours.search(
        scene.grid,
        position,
        active,
        scene.max_neighbours,
        disc.r_e,
        scene.neighbour_skin,
        cache,
        batch_axis,
    )
    pairs = operators.make_pairs(nbrs.index, position, disc.weight, disc.r_e)
    return nbrs, visible(coupling, pairs, disc.r_e), cache


def _pressure_inputs(
    state: State,
    pairs_k: operators.Pairs,
    pairs: operators.Pairs,
    n_star: Field,
    surface: Mask,
    position: Positions,
    velocity: Velocities,
    reference_dt: Scalar,
    coupling: Coupling | None,
) -> fluid.PressureInputs:
    """What the pressure stage may use: the tentative positions and velocities
    (r*, u*) with their pairs, number density and surface, the step's start, and
    the reference step."""
    return fluid.PressureInputs(
        pairs=pairs,
        n_star=n_star,
        position=position,
        velocity=velocity,
        surface=surface,
        pairs_k=pairs_k,
        velocity_k=state.velocity,
        pressure_k=state.pressure,
        kind=state.kind,
        active=state.active,
        reference_dt=reference_dt,
        coupling=coupling,
    )


def _advanced(
    state: State,
    dt: Scalar,
    x_star: Positions,
    u_star: Velocities,
    u_prime: Velocities,
    pressure: Field,
    cache: neighbours.NeighbourCache | None,
) -> State:
    """The state after the fluid stages: r = r* + dt u', u = u* + u', the new
    pressure, and the lists to carry to the next step (when the state carries
    lists)."""
    return dataclasses.replace(
        state,
        time=state.time + dt,
        step=state.step + 1,
        dt=dt,
        position=x_star + dt * u_prime,
        velocity=u_star + u_prime,
        pressure=pressure,
        neighbours=cache,
    )


def _info(
    solution: fluid.PressureSolution,
    nbrs_k: neighbours.Neighbours,
    nbrs: neighbours.Neighbours,
) -> StepInfo:
    """The step's diagnostics from its pressure stage and its two searches."""
    return StepInfo(
        pressure_iterations=solution.iterations,
        pressure_residual=solution.residual,
        pressure_converged=solution.converged,
        neighbour_overflow=nbrs_k.neighbour_overflow | nbrs.neighbour_overflow,
        cell_overflow=nbrs_k.cell_overflow | nbrs.cell_overflow,
        outside=jnp.any(nbrs_k.outside) | jnp.any(nbrs.outside),
        surface_count=jnp.sum(solution.free, dtype=jnp.int32),
        unstable=solution.unstable,
    )


def _take_out_escaped(
    scene: Scene, state: State, info: StepInfo, outside: Mask
) -> tuple[State, StepInfo]:
    """Take the fluid particles `outside` the domain box out of the run (made
    inactive, parked at the grid's origin as the pool is, counted in
    `State.escaped`) while no more than `Scene.escape_limit` have escaped; the
    step's `outside` then flags what is left: any other particle outside, or a
    count beyond the limit. Non-finite positions are never taken out (they are
    `Result.nonfinite_state`)."""
    if scene.escape_limit <= 0:
        return state, info
    finite = finite_rows(state.position)
    fluid = state.kind == int(Kind.FLUID)
    leaving = outside & state.active & fluid & finite
    escaped = state.escaped + jnp.sum(leaving, dtype=state.escaped.dtype)
    origin = jnp.asarray(scene.grid.origin, state.position.dtype)
    state = dataclasses.replace(
        state,
        active=state.active & ~leaving,
        position=jnp.where(leaving[:, None], origin, state.position),
        velocity=jnp.where(leaving[:, None], 0.0, state.velocity),
        pressure=jnp.where(leaving, 0.0, state.pressure),
        escaped=escaped,
    )
    still = jnp.any(outside & ~leaving & state.active) | (escaped > scene.escape_limit)
    return state, eqx.tree_at(lambda i: i.outside, info, still)


def _record(
    scene: Scene,
    params: Params,
    new: State,
    info: StepInfo,
    pool_short: Bool[Array, ""],
    mobile: Mask,
    forced: Float[Array, "n d"],
    counted: Mask | None = None,
) -> State:
    """Record the step's first failure in the state's result: a step beyond a
    stability limit (over the `mobile` particles), overflows, an empty pool, a
    particle out of the domain, an unconverged pressure solve, a non-finite
    state; and
    the step's largest acceleration by forces (`forced`: gravity and viscosity,
    and the pressure where it is a force: `pressure_is_force` of the solver). The
    finiteness is checked on the `counted` particles (None: all)."""
    speed = jnp.sqrt(last_axis_dot(new.velocity, new.velocity))
    courant = jnp.max(jnp.where(mobile, speed, 0.0)) * params.dt / scene.spacing
    # A diagnostic of the dt choice, which is a constant to the gradient (and the
    # norm's derivative at a particle at rest is not finite).
    forced = jax.lax.stop_gradient(forced)
    forced = jnp.sqrt(last_axis_dot(forced, forced))
    acceleration = jnp.max(jnp.where(mobile, forced, 0.0), initial=0.0)
    viscous = 2 * scene.dim * params.viscosity * params.dt / scene.lam
    checked = new.active if counted is None else new.active & counted
    finite = jnp.all(finite_rows(new.position, new.velocity, new.pressure) | ~checked)
    # A step beyond its stability limit comes first: the overflows and escapes
    # of that step are its consequences (a dt 40 times too large read as a
    # full cell or a particle out of the domain, naming the wrong setting).
    result = update_result(
        new.result,
        (courant > scene.courant_limit)
        | (viscous > scene.viscous_limit)
        | info.unstable,
        Result.step_too_large,
    )
    result = update_result(result, info.cell_overflow, Result.cell_overflow)
    result = update_result(result, info.neighbour_overflow, Result.neighbour_overflow)
    result = update_result(result, pool_short, Result.pool_exhausted)
    result = update_result(result, info.outside, Result.left_domain)
    result = update_result(
        result, ~info.pressure_converged, Result.pressure_not_converged
    )
    result = update_result(result, ~finite, Result.nonfinite_state)
    return dataclasses.replace(new, result=result, acceleration=acceleration)


def mobile_maximum(values: Float[Array, " n"], state: State) -> Scalar:
    """The largest of `values` over the active fluid and body particles (0 if
    none)."""
    mobile = fluid.is_mobile(state.kind, state.active)
    return jnp.max(jnp.where(mobile, values, 0.0), initial=0.0)


def time_step_limits(scene: Scene, params: Params, state: State) -> dict[str, Scalar]:
    """Every limit `Adaptive` takes the smallest of, by name [s] (inf where a limit
    does not apply); for a Scene with fixed steps, only "dt" (`Params.dt`).

    Useful to see which limit sets the step of a flow: observe it in `simulate`.
    """
    stepping = scene.time_step
    limits = {"dt_max" if stepping is not None else "dt": params.dt}
    if stepping is None:
        return limits
    l0 = scene.spacing
    speed = mobile_maximum(jnp.linalg.norm(state.velocity, axis=-1), state)
    inf = jnp.asarray(jnp.inf, params.dt.dtype)
    courant = stepping.courant_for(scene)
    limits["courant"] = jnp.where(
        speed > 0, courant * l0 / jnp.where(speed > 0, speed, 1.0), inf
    )
    accel = state.acceleration
    limits["force"] = jnp.where(
        accel > 0,
        stepping.force * jnp.sqrt(l0 / jnp.where(accel > 0, accel, 1.0)),
        inf,
    )
    nu = params.viscosity
    limits["viscous"] = jnp.where(
        nu > 0,
        stepping.stability
        * scene.viscous_limit
        * scene.lam
        / (2 * scene.dim * jnp.where(nu > 0, nu, 1.0)),
        inf,
    )
    limits["solver"] = stepping.stability * scene.solver.time_step_limit(
        scene.discretisation, params
    )
    for model in scene.body_models:
        limits[model.name] = stepping.stability * model.time_step_limit(
            scene.discretisation, params, state
        )
    return {k: jnp.asarray(v, params.dt.dtype) for k, v in limits.items()}


def time_step(scene: Scene, params: Params, state: State) -> Scalar:
    """The dt of the next step: `Params.dt` with fixed steps, else the smallest of
    `time_step_limits`.

    The choice is a constant to the gradient (`stop_gradient`): the gradient of a
    rollout is that of the same steps taken with those dt values. The dt is a
    numerical choice, not a model of the flow: the derivative of a limit (a
    maximum over particles) jumps whenever another particle or another limit
    takes over, and carried through thousands of steps it would add such jumps
    to every gradient while changing the modelled physics not at all.
    """
    if scene.time_step is None:
        return params.dt
    limits = time_step_limits(scene, params, state)
    dt = jnp.min(jnp.stack(list(limits.values())))
    return jax.lax.stop_gradient(dt)


def step(
    scene: Scene,
    params: Params,
    state: State,
    *,
    dt: Scalar | None = None,
    batch_axis: str | None = None,
) -> tuple[State, StepInfo]:
    """Advance `state` by one time step: `dt` if given, else `params.dt`, or with
    adaptive steps (`Scene.time_step`) `time_step(scene, params, state)` (not
    retried if it fails: `simulate` retries).

    Failures are recorded in the returned `state.result` (first failure wins); this
    function never raises at run time. Use `simulate` for rollouts. For a loop of
    steps of your own, start from `with_neighbour_lists(scene, state)`: the state
    then carries each step's neighbour lists to the next, which searches once per
    step instead of twice (as `simulate` does).

    Args:
        scene, params, state: the simulation.
        dt: the step's length [s]. `params.dt` stays the largest step, and with
            `params.relaxation_step` None the reference step of the pressure
            source's density relaxation (`PressureInputs.reference_dt`), as in an
            adaptive rollout, whose steps this replays.
        batch_axis: when this call runs under `jax.vmap(..., axis_name=name)`,
            `name`: the batch then decides jointly whether the carried neighbour
            lists can be reused (`neighbours.reuse_or_build`).

    Returns:
        The new state and this step's diagnostics.
    """
    check_compatible(scene, params, state)
    return _jit_step(scene, params, state, batch_axis, dt)


@eqx.filter_jit
def _jit_step(
    scene: Scene,
    params: Params,
    state: State,
    batch_axis: str | None,
    dt: Scalar | None,
) -> tuple[State, StepInfo]:
    if dt is None and scene.time_step is not None:
        dt = time_step(scene, params, state)
    return _step(scene, params, state, batch_axis, dt)


def with_neighbour_lists(scene: Scene, state: State) -> State:
    """`state` carrying (empty) neighbour lists, so that each `step` passes its
    lists on to the next (a new search only when some pair has moved apart or
    together by `Scene.neighbour_skin`, `neighbours.lists_hold`). Unchanged if it
    carries lists already or the Scene has no skin."""
    if scene.neighbour_skin <= 0 or state.neighbours is not None:
        return state
    cache = neighbours.NeighbourCache.empty(
        state.position, state.active, scene.max_neighbours
    )
    return dataclasses.replace(state, neighbours=cache)


def without_neighbour_lists(state: State) -> State:
    """`state` without carried neighbour lists (as `simulate` returns states)."""
    if state.neighbours is None:
        return state
    return dataclasses.replace(state, neighbours=None)
