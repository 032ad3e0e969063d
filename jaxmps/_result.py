"""Result codes threaded through every step and raised once, at the end of a run."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Int


class Result(eqx.Enumeration):
    """Outcome of a step or a rollout. The first failure wins; later ones are ignored.

    Each message says which setting to change.
    """

    successful = ""
    neighbour_overflow = (
        "A particle had more neighbours than `Scene.max_neighbours` slots. Raise it "
        "(scene override `max_neighbours=...`, or `make_scene(neighbour_margin=...)`)."
    )
    cell_overflow = (
        "The neighbour-search cells around a particle held more particles than "
        "`Scene.grid.candidate_capacity`. Raise it (scene override "
        "`candidate_capacity=...`, or `make_scene(candidate_margin=...)`)."
    )
    pressure_not_converged = (
        "The pressure Poisson solve did not reach its tolerance within "
        "`SemiImplicit.max_iterations` iterations. Raise `max_iterations`, loosen "
        "`SemiImplicit.rtol`, or reduce `dt`."
    )
    nonfinite_state = (
        "A particle position, velocity or pressure became NaN or infinite. Reduce `dt` "
        "(the run was likely unstable), or run in float64 (`--x64`)."
    )
    left_domain = (
        "A particle left the domain box `Scene.grid`: a body or wall particle, or "
        "more fluid particles than `Scene.escape_limit` (spray taken out of the "
        "run, counted in `State.escaped`). Enlarge the domain (scene override "
        "`domain_margin=...`), allow more spray (`escape_limit=...`), or find why "
        "it escaped (splash over a wall, instability)."
    )
    pool_exhausted = (
        "The inflow needed more inactive particles than the pool holds. Raise the "
        "capacity (scene override `pool=...`, or `make_scene(capacity=...)`)."
    )
    step_too_large = (
        "The time step is beyond a stability limit: the Courant number max|u| dt / l0 "
        "exceeded `Scene.courant_limit`, the viscous number 2 d nu dt / lambda "
        "exceeded `Scene.viscous_limit`, (explicit solver) c dt / l0 exceeded "
        "`Explicit.sound_courant`, or the forces carried a particle beyond r_e "
        "in one step. Reduce `dt` (scene override `dt=...`), or "
        "let the run choose it (scene setting `dt='adaptive'`, the default)."
    )
    time_step_below_minimum = (
        "The adaptive time step fell below `Adaptive.dt_min` (by default 1e-2 x "
        "the largest step): one of `jaxmps.time_step_limits` asked for less. "
        "Either a particle became too fast or too strongly accelerated for the "
        "resolution, usually a sign of an instability (a particle squeezed into "
        "a wall, a body overlapping another), or the viscosity is so large that "
        "its diffusion limit is tiny. Check the setup and the viscosity, or lower "
        "the bound (scene setting `dt_min=...`)."
    )
    too_many_steps = (
        "A save interval needed more steps than the bound on steps per save "
        "(`simulate(max_steps=...)`; `jaxmps.run(max_steps_per_save=...)`, "
        "`--max-steps-per-save` on the command line). Raise it, or save more "
        "often (`save_every`)."
    )
    contact_overflow = (
        "A DEM grain had more contact candidates (grains and walls within its "
        "contact distance and skin) than `Grains.contact_capacity` slots, or the "
        "grains' search cells held more than their candidate capacity. Raise "
        "them (`jaxmps.add_grains(contact_capacity=..., candidate_capacity=...)`; "
        "scene setting `contact_capacity=...`), or find why grains crowd (an "
        "overlapping start, a stiffness too low for the load)."
    )
    slab_overflow = (
        "In a run split over devices by slabs (`jaxmps.simulate_slabs`), a slab "
        "held more particles than its slots, or more particles crossed or lay "
        "near one of its cuts than the halo's slots: the flow gathered where the "
        "start's layout had few particles. Raise `simulate_slabs(slack=...)` "
        "(slots per slab and per halo, as a multiple of the start's largest "
        "counts), or split over fewer devices."
    )


# Equinox's `Enumeration` has no public accessor for an item's integer code, which
# run files store and batched results are compared by, nor for its name, which
# reports print; these five functions are the only places that read its private
# fields.


def result_code(result: Result) -> Int[ArrayLike, "*batch"]:
    """The integer code of `result` (0 for `Result.successful`); batched results
    give an array of codes."""
    return result._value


def result_from_code(code: int) -> Result:
    """The `Result` item with the integer code `code` (host-side)."""
    for name in Result._name_to_item:
        item = getattr(Result, name)
        if int(np.asarray(item._value)) == int(code):
            return item
    raise ValueError(f"No jaxmps.Result has the integer code {code}.")


def traced_result(code: Int[ArrayLike, ""]) -> Result:
    """The `Result` item of an integer code that may be traced (inside jit)."""
    out = Result.successful
    for name in Result._name_to_item:
        item = getattr(Result, name)
        out = Result.where(code == item._value, item, out)
    return out


def result_name(result: Result) -> str:
    """The name of a (concrete, unbatched) `Result` item: "successful",
    "nonfinite_state", ..."""
    return next(
        name for name in Result._name_to_item if bool(result == getattr(Result, name))
    )


def result_message(result: Result) -> str:
    """The message of a (concrete, unbatched) `Result` item."""
    return Result._index_to_message[int(np.asarray(result_code(result)))]


def update_result(old: Result, pred: Bool[ArrayLike, ""], item: Result) -> Result:
    """Return `item` if `pred` holds and nothing failed before, else `old`."""
    return Result.where(jnp.logical_and(pred, old == Result.successful), item, old)


class StepInfo(eqx.Module):
    """Diagnostics of one step (not part of the State; `simulate` can save them)."""

    pressure_iterations: Int[Array, ""]
    pressure_residual: Float[Array, ""]
    pressure_converged: Bool[Array, ""]
    neighbour_overflow: Bool[Array, ""]
    cell_overflow: Bool[Array, ""]
    outside: Bool[Array, ""]
    surface_count: Int[Array, ""]
    unstable: Bool[Array, ""]  # a solver-specific stability limit was exceeded
