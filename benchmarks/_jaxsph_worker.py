"""JAX-SPH side of `side_by_side.py`: one 2-D dam break, timed, as one JSON line.

Runs inside the JAX-SPH virtual environment (Python <= 3.11.0, jax-sph 0.1.0, its
pinned jax), so it imports neither `jaxmps` nor `_common`. The dam break is set up
here against JAX-SPH's public API (the PyPI wheel ships no `cases/`):

* geometry as `jaxmps.scenes.dam_break`: a `column_width` x 2 `column_width` water
  column (default 0.146 x 0.292 m) at the left wall of a closed tank
  4 x `column_width` long and 3 x `column_width` high, dx = column_width / n_across,
  walls of `solver.n_walls` (3) particle layers (`jax_sph.utils.pos_box_2d`) and a
  periodic box 10 % of the column height larger than the tank so that no particle
  interacts across the periodic boundary;
* physics in SI units: rho = 1000 kg/m^3, dynamic viscosity 1e-3 Pa s, g = 9.81
  m/s^2, u_ref = sqrt(2 g H), c = 10 u_ref (JAX-SPH's `c_ref_factor`), Tait EoS with
  gamma = 1 and no background pressure;
* solver as JAX-SPH's own dam break configuration: standard WCSPH (`solver.name =
  "SPH"`), density evolution, artificial viscosity alpha = 0.1, generalized wall
  boundary condition (`is_bc_trick`), no transport velocity; everything else
  JAX-SPH's defaults (quintic spline kernel with h = dx, cut-off 3 dx; dt from its
  CFL rule with cfl = 0.25; `jaxmd_vmap` neighbour list, capacity multiplier 1.25);
* the step is `jax_sph.integrator.si_euler` (position update, neighbour-list update,
  `WCSPH` forward, boundary conditions), rolled out with `jax.lax.scan`. A
  neighbour-list overflow during the rollout (its `did_buffer_overflow` flag, which
  accumulates over updates) makes the worker reallocate the list with more room
  per particle (`extra_capacity`), recompile and run again.

Timing: compile (trace + lower, XLA compile) separately via
`jax.jit(rollout).lower(...).compile()`; then one untimed warm-up call and the best
of `--repeats` timed calls (one when the warm-up call took longer than
`--max-timed-s`), each ended by `jax.block_until_ready`.

Usage (normally called by `side_by_side.py`):
    python _jaxsph_worker.py --n-across 50 --steps 200 --dtype float64
"""

import argparse
import contextlib
import json
import os
import platform
import resource
import sys
import time


def _rss_mib() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 1024 if sys.platform != "darwin" else r / 1024**2


def build(n_across: int, column_width: float, dtype: str):
    """Case, solver, step and neighbour list of the dam break (everything but time)."""
    import jax

    jax.config.update("jax_enable_x64", dtype == "float64")
    import jax.numpy as jnp
    import numpy as np
    from jax_sph import partition
    from jax_sph.case_setup import SimulationSetup
    from jax_sph.defaults import set_defaults
    from jax_sph.integrator import si_euler
    from jax_sph.jax_md.partition import Sparse
    from jax_sph.solver import WCSPH
    from jax_sph.utils import Tag, pos_box_2d, pos_init_cartesian_2d
    from omegaconf import OmegaConf

    a = float(column_width)
    col = np.array([a, 2.0 * a])  # water column (width, height)
    tank = np.array([4.0 * a, 3.0 * a])  # inner tank (length, height)
    gravity = 9.81

    cfg = set_defaults(OmegaConf.create({}))
    cfg.config = "side_by_side_dam_break.yaml"  # only its base name is used
    cfg.dtype = dtype
    cfg.case.dim = 2
    cfg.case.dx = a / n_across
    cfg.case.rho_ref = 1000.0
    cfg.case.viscosity = 1.0e-3
    cfg.case.g_ext_magnitude = gravity
    cfg.case.u_ref = float(np.sqrt(2.0 * gravity * col[1]))
    cfg.solver.name = "SPH"
    cfg.solver.is_bc_trick = True
    cfg.solver.density_evolution = True
    cfg.solver.artificial_alpha = 0.1
    cfg.solver.dt = None  # JAX-SPH's CFL rule
    cfg.solver.t_end = 1.0  # unused here (sets its sequence_length only)

    class DamBreak(SimulationSetup):
        """Water column at the left wall of a closed tank, walls of n_walls layers."""

        def __init__(self, cfg):
            super().__init__(cfg)
            n_walls = cfg.solver.n_walls
            self.offset_vec = np.full(2, n_walls * cfg.case.dx)

        def _box_size2D(self, n_walls):
            margin = 0.1 * col[1]
            return tank + 2 * n_walls * self.case.dx + margin

        def _box_size3D(self, n_walls):
            raise NotImplementedError("2-D only")

        def _init_walls_2d(self, dx, n_walls):
            return pos_box_2d(tank, dx, n_walls)

        def _init_walls_3d(self, dx, n_walls):
            raise NotImplementedError("2-D only")

        def _init_pos2D(self, box_size, dx, n_walls):
            walls = np.asarray(self._init_walls_2d(dx, n_walls))
            fluid = np.asarray(pos_init_cartesian_2d(col, dx)) + n_walls * dx
            r = jnp.asarray(np.concatenate([walls, fluid]))
            tag = np.concatenate(
                [
                    np.full(len(walls), int(Tag.SOLID_WALL)),
                    np.full(len(fluid), int(Tag.FLUID)),
                ]
            )
            return r, jnp.asarray(tag, dtype=int)

        def _init_velocity2D(self, r):
            return jnp.zeros_like(r)

        def _init_velocity3D(self, r):
            return jnp.zeros_like(r)

        def _external_acceleration_fn(self, r):
            return jnp.zeros_like(r).at[:, 1].set(-self.case.g_ext_magnitude)

        def _boundary_conditions_fn(self, state):
            wall = (state["tag"] == Tag.SOLID_WALL)[:, None]
            for key in ("u", "v", "dudt", "dvdt"):
                state[key] = jnp.where(wall, 0.0, state[key])
            return state

    # JAX-SPH prints its set-up (dt, particle count) to stdout: keep stdout for JSON.
    with contextlib.redirect_stdout(sys.stderr):
        case = DamBreak(cfg)
        (cfg, box_size, state, g_ext_fn, bc_fn, nw_fn, eos, _, disp_fn, shift_fn) = (
            case.initialize()
        )
    solver = WCSPH(
        disp_fn,
        eos,
        g_ext_fn,
        cfg.case.dx,
        cfg.case.dim,
        cfg.solver.dt,
        cfg.case.c_ref,
        eta_limiter=cfg.solver.eta_limiter,
        solver=cfg.solver.name,
        kernel=cfg.kernel.name,
        is_bc_trick=cfg.solver.is_bc_trick,
        is_rho_evol=cfg.solver.density_evolution,
        artificial_alpha=cfg.solver.artificial_alpha,
        is_free_slip=cfg.solver.free_slip,
        is_rho_renorm=cfg.solver.density_renormalize,
        is_heat_conduction=cfg.solver.heat_conduction,
    )
    n = int(state["r"].shape[0])
    neighbor_fn = partition.neighbor_list(
        disp_fn,
        box_size,
        r_cutoff=solver._kernel_fn.cutoff,
        backend=cfg.nl.backend,
        capacity_multiplier=1.25,
        mask_self=False,
        format=Sparse,
        num_particles_max=n,
        num_partitions=cfg.nl.num_partitions,
        pbc=np.array(cfg.case.pbc),
    )
    advance = si_euler(cfg.solver.tvf, solver.forward_wrapper(), shift_fn, bc_fn, nw_fn)
    n_fluid = int((np.asarray(state["tag"]) == int(Tag.FLUID)).sum())
    info = {
        "dx": float(cfg.case.dx),
        "dt": float(cfg.solver.dt),
        "c_ref": float(cfg.case.c_ref),
        "u_ref": float(cfg.case.u_ref),
        "n_walls": int(cfg.solver.n_walls),
        "kernel": str(cfg.kernel.name),
        "kernel_cutoff": float(solver._kernel_fn.cutoff),
        "solver": str(cfg.solver.name),
        "box_size": [float(x) for x in box_size],
        "capacity": n,
        "n_fluid": n_fluid,
        "n_wall": n - n_fluid,
        "column": [float(x) for x in col],
        "tank": [float(x) for x in tank],
    }
    return info, state, advance, neighbor_fn, float(cfg.solver.dt)


def run(args) -> dict:
    import jax
    import jax.numpy as jnp

    t_build = time.perf_counter()
    info, state0, advance, neighbor_fn, dt = build(
        args.n_across, args.column_width, args.dtype
    )
    n = info["capacity"]
    n_steps = args.steps

    def rollout(state, nbrs):
        def body(carry, _):
            s, nb = carry
            s, nb = advance(dt, s, nb)
            return (s, nb), None

        (state, nbrs), _ = jax.lax.scan(body, (state, nbrs), None, length=n_steps)
        return state, nbrs

    first_step = jax.jit(advance)
    rollout_jit = jax.jit(rollout)
    build_s = time.perf_counter() - t_build

    extra = 0
    rebuilds = 0
    while True:
        nbrs = neighbor_fn.allocate(state0["r"], num_particles=n, extra_capacity=extra)
        # As JAX-SPH's simulate: one zero-length step to get the initial accelerations.
        state, nbrs = jax.block_until_ready(first_step(0.0, dict(state0), nbrs))
        t0 = time.perf_counter()
        lowered = rollout_jit.lower(state, nbrs)
        t1 = time.perf_counter()
        compiled = lowered.compile()
        t2 = time.perf_counter()
        # Untimed warm-up call; it also tells whether the neighbour list overflowed.
        t3 = time.perf_counter()
        out = jax.block_until_ready(compiled(state, nbrs))
        warm_s = time.perf_counter() - t3
        if not bool(out[1].did_buffer_overflow):
            break
        rebuilds += 1
        extra += 2
        print(
            f"jax-sph: neighbour list overflow (capacity {nbrs.idx.shape[1]}); "
            f"reallocating with extra_capacity={extra} per particle",
            file=sys.stderr,
        )
        if rebuilds > 10:
            raise RuntimeError("neighbour list keeps overflowing")

    repeats = args.repeats if warm_s <= args.max_timed_s else 1
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = jax.block_until_ready(compiled(state, nbrs))
        times.append(time.perf_counter() - t)
    best = min(times)
    final, final_nbrs = out
    finite = bool(jnp.all(jnp.isfinite(final["r"])) & jnp.all(jnp.isfinite(final["u"])))
    fluid = final["tag"] == 0
    u_max = float(jnp.max(jnp.where(fluid, jnp.linalg.norm(final["u"], axis=1), 0.0)))

    import importlib.metadata as md

    import jaxlib

    record = {
        "code": "jax-sph",
        **info,
        "n_steps": n_steps,
        "simulated_time": n_steps * dt,
        "dtype": str(state["r"].dtype),
        "jax_enable_x64": bool(jax.config.jax_enable_x64),
        "build_s": build_s,
        "trace_lower_s": t1 - t0,
        "compile_s": t2 - t1,
        "run_s_best": best,
        "run_s_all": times,
        "ms_per_step": 1e3 * best / n_steps,
        "particle_steps_per_s": n * n_steps / best,
        "wall_per_simulated_s": best / (n_steps * dt),
        "neighbour_capacity": int(final_nbrs.idx.shape[1]),
        "neighbour_extra_capacity": extra,
        "neighbour_rebuilds": rebuilds,
        "finite": finite,
        "fluid_u_max": u_max,
        "peak_rss_mib": _rss_mib(),
        "versions": {
            "python": platform.python_version(),
            "jax": jax.__version__,
            "jaxlib": jaxlib.__version__,
            "jax_sph": md.version("jax-sph"),
        },
        "backend": jax.default_backend(),
        "loadavg_1min_end": os.getloadavg()[0],
    }
    return record


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n-across", type=int, required=True, help="particles across")
    p.add_argument("--column-width", type=float, default=0.146)
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--max-timed-s", type=float, default=20.0)
    p.add_argument("--dtype", choices=("float32", "float64"), default="float64")
    args = p.parse_args(argv)
    print(json.dumps(run(args)))


if __name__ == "__main__":
    main()
