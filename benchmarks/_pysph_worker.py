"""PySPH side of `side_by_side.py`: the 2-D WCSPH dam break, timed, as one JSON line.

Runs inside the PySPH virtual environment (`benchmarks/.venv-pysph`, PySPH 1.0b2,
Python 3.11), so it imports neither `jaxmps` nor `_common`.

The case is the example shipped with PySPH, `pysph.examples.dam_break_2d`, with
its default scheme and settings: WCSPH (`WCSPHScheme`, Tait equation of state with
gamma = 7, c0 = 10 sqrt(2 g H), artificial viscosity alpha = 0.1, continuity
density, Hughes-Graham wall correction, smoothing length updated from the density),
Wendland quintic kernel, predictor-corrector integrator (`PECIntegrator`) and
adaptive time step (CFL 0.3, the first 50 steps damped). Geometry: a 1 x 2 m water
column in a 4 x 4 m open tank with 4 layers of wall particles.

The example computes h = hdx dx and m = rho0 dx^2 from its default spacing (0.03 m)
once, at import, and keeps those values when another `--dx` is given, so a finer
spacing would run with the coarse h and mass (and, as h follows m / rho, keep
them). Here both are reset from the requested spacing, with the example's own
formulas, before the particles are built, and checked on the built arrays.

Timing (wall clock, `time.perf_counter`):

* `setup_s`: everything before the timed steps: importing PySPH, building the
  particles, generating and compiling the Cython code for the equations and the
  integrator (or loading it from the cache under ~/.pysph/source) and an untimed
  warm-up of `--warmup` steps (default 50, which covers the damped start of the
  time step); the parts are reported separately (`import_s`, `build_s`,
  `compile_s`, `app_setup_s`, `warmup_s`).
* `run_s`: best of `--repeats` blocks of `--steps` steps, each one call of PySPH's
  own `Solver.solve` with the step limit raised by `--steps`. Each block continues
  the same simulation from where the previous one stopped (so later blocks run
  later, slightly more disturbed states of the dam break) and includes one extra
  acceleration evaluation that `Solver.solve` makes on entry (about one step's
  worth of work per block). No output files are written and no progress is shown.
  `dt` is the mean step of that block (its simulated time / steps).

The compiled code does not depend on `--dx`: it is built once for serial and once
for OpenMP runs (some 15 s each on 2 cores) and then loaded from the cache.
`peak_rss_mib` adds the peak resident set of this process and that of its largest
child (the C++ compiler, when it ran), both from `resource.getrusage`.

OpenMP: `--openmp` compiles and runs the equations with OpenMP (PySPH's dynamic,64
schedule); the thread count is OpenMP's default (OMP_NUM_THREADS, otherwise the
number of cores) unless `--threads` is given.

`--count-only` builds the particles for `--dx` and prints their counts without
compiling or running anything (for choosing `--dx` to match a particle count).

Usage (normally called by `side_by_side.py`):
    python _pysph_worker.py --dx 0.02 --steps 200 --openmp --repeats 3
    python _pysph_worker.py --dx 0.01 --count-only
"""

import argparse
import contextlib
import json
import os
import platform
import resource
import shutil
import sys
import tempfile
import time


class _CountOnly(Exception):
    """Raised after the particles are built to stop the set-up before compiling."""


def _mib(ru_maxrss: int) -> float:
    """ru_maxrss in MiB (kilobytes on Linux, bytes on macOS)."""
    return ru_maxrss / (1024**2 if sys.platform == "darwin" else 1024)


@contextlib.contextmanager
def _stdout_to_stderr():
    """Send everything written to stdout (Python and file descriptor 1) to stderr.

    PySPH and the compiler it calls print progress to stdout; the worker's stdout
    must end with its JSON line only.
    """
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def make_app(count_only: bool = False):
    """The example's application class, with h and m taken from the requested dx.

    Returns an instance of a subclass of `pysph.examples.dam_break_2d.DamBreak2D`.
    With `count_only`, `setup` stops with `_CountOnly` once the particles exist.
    """
    from pysph.examples import dam_break_2d as example

    class TimedDamBreak2D(example.DamBreak2D):
        """DamBreak2D with h, m from the chosen spacing and a timed compile."""

        compile_s = None
        build_s = None

        def create_particles(self):
            """Build the example's particles with h = hdx dx and m = rho0 dx^2.

            The example reads h and m from module constants fixed at import; they
            are set from this run's spacing first, then checked on the arrays.
            """
            h = self.hdx * self.dx
            mass = example.ro * self.dx**2
            example.h = h
            example.m = mass
            t0 = time.perf_counter()
            arrays = super().create_particles()
            self.build_s = time.perf_counter() - t0
            for pa in arrays:
                if len(pa.x) and not (
                    abs(pa.h.min() - h) <= 1e-12 * h
                    and abs(pa.h.max() - h) <= 1e-12 * h
                    and abs(pa.m.min() - mass) <= 1e-12 * mass
                    and abs(pa.m.max() - mass) <= 1e-12 * mass
                ):
                    raise RuntimeError(f"h or m of {pa.name!r} not reset from dx")
            self.h_used, self.m_used = h, mass
            if count_only:
                self.counts = {
                    pa.name: int(pa.get_number_of_particles()) for pa in arrays
                }
                raise _CountOnly
            return arrays

        def create_solver(self):
            """The example's solver, its `setup` (code generation + compile) timed."""
            solver = super().create_solver()
            setup = solver.setup
            app = self

            def timed_setup(*args, **kw):
                t0 = time.perf_counter()
                out = setup(*args, **kw)
                app.compile_s = time.perf_counter() - t0
                return out

            solver.setup = timed_setup
            return solver

    return TimedDamBreak2D(fname="pysph_worker_dam_break_2d")


def app_argv(args, output_dir: str) -> list:
    """PySPH command line for the example: spacing, quiet, no output of any kind."""
    argv = [
        "--dx",
        repr(args.dx),
        "--directory",
        output_dir,
        "--disable-output",
        "--pfreq",
        str(2**30),
        "--quiet",
        "--loglevel",
        "none",
        "--logfile",
        "",
    ]
    if args.openmp:
        argv.append("--openmp")
    return argv


def count_particles(args) -> dict:
    """Particle counts for `--dx` (no compile, no solve)."""
    out_dir = tempfile.mkdtemp(prefix="pysph_worker_")
    try:
        with _stdout_to_stderr():
            app = make_app(count_only=True)
            try:
                app.setup(app_argv(args, out_dir))
            except _CountOnly:
                pass
            else:
                raise RuntimeError("particle set-up did not stop after building")
    finally:
        shutil.rmtree(out_dir, ignore_errors=True)
    n_fluid = app.counts["fluid"]
    n_solid = app.counts["boundary"]
    return {
        "code": "PySPH",
        "dx": args.dx,
        "particles": n_fluid + n_solid,
        "n_fluid": n_fluid,
        "n_solid": n_solid,
        "h": app.h_used,
        "mass": app.m_used,
    }


def _solve_block(solver, n_steps: int):
    """Advance `solver` `n_steps` steps by its own `solve`: (wall, simulated, steps)."""
    count0, t_sim0 = solver.count, solver.t
    solver.set_max_steps(count0 + n_steps)
    t0 = time.perf_counter()
    solver.solve(show_progress=False)
    wall = time.perf_counter() - t0
    done = solver.count - count0
    if done != n_steps:
        raise RuntimeError(
            f"solver stopped after {done} of {n_steps} steps (t = {solver.t:g}, "
            f"final time {solver.tf:g})"
        )
    return wall, solver.t - t_sim0, done


def run(args, t_start: float) -> dict:
    """Set up, compile, warm up and time the example; the JSON record."""
    import numpy as np

    load_start = os.getloadavg()[0]
    out_dir = tempfile.mkdtemp(prefix="pysph_worker_")
    try:
        with _stdout_to_stderr():
            t0 = time.perf_counter()
            import pysph
            from compyle.config import get_config

            app = make_app()
            import_s = time.perf_counter() - t0

            t0 = time.perf_counter()
            app.setup(app_argv(args, out_dir))
            app_setup_s = time.perf_counter() - t0
            solver = app.solver

            openmp = bool(get_config().use_openmp)
            if openmp:
                from pysph.base import omp_threads

                if args.threads:
                    omp_threads.set_number_of_threads(args.threads)
                n_threads = int(omp_threads.get_number_of_threads())
            else:
                n_threads = 1

            dt_initial = float(solver.dt)
            warmup_s = 0.0
            if args.warmup > 0:
                warmup_s = _solve_block(solver, args.warmup)[0]
            setup_s = time.perf_counter() - t_start

            blocks = [_solve_block(solver, args.steps) for _ in range(args.repeats)]
    finally:
        shutil.rmtree(out_dir, ignore_errors=True)

    times = [b[0] for b in blocks]
    best = min(range(len(blocks)), key=lambda i: times[i])
    run_s, sim_s, n_steps = blocks[best]
    dt = sim_s / n_steps

    arrays = {pa.name: pa for pa in solver.particles}
    fluid, solid = arrays["fluid"], arrays["boundary"]
    n_fluid = int(fluid.get_number_of_particles())
    n_solid = int(solid.get_number_of_particles())
    n = n_fluid + n_solid
    x, y = fluid.get("x", "y")
    u, v = fluid.get("u", "v")
    finite = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(y)))
    speed = np.hypot(u, v)
    u_max = float(np.max(speed)) if np.all(np.isfinite(speed)) else float("nan")

    import importlib.metadata as md

    omp_vars = ("OMP_", "GOMP_")

    peak_self = _mib(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
    peak_children = _mib(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)

    method = (
        f"Setup (import, particles, code generation and Cython compile or cache "
        f"load, {args.warmup} untimed warm-up steps) timed once as setup_s; then "
        f"{args.repeats} consecutive blocks of {n_steps} steps, each one call of "
        f"PySPH's Solver.solve continuing the same run (adaptive dt, one extra "
        f"acceleration evaluation on entry to each call, no output), timed with "
        f"perf_counter; run_s is the fastest block."
    )

    return {
        "code": "PySPH",
        "version": pysph.__version__,
        "python": platform.python_version(),
        "openmp": openmp,
        "n_threads": n_threads,
        "dx": args.dx,
        "particles": n,
        "n_fluid": n_fluid,
        "n_solid": n_solid,
        "h": float(app.h_used),
        "mass": float(app.m_used),
        "scheme": str(app.options.scheme),
        "integrator": type(solver.integrator).__name__,
        "kernel": type(solver.kernel).__name__,
        "dt": dt,
        "dt_initial": dt_initial,
        "dt_end": float(solver.dt),
        "n_steps": n_steps,
        "simulated_time": sim_s,
        "t_end": float(solver.t),
        "setup_s": setup_s,
        "import_s": import_s,
        "build_s": app.build_s,
        "compile_s": app.compile_s,
        "app_setup_s": app_setup_s,
        "warmup_steps": args.warmup,
        "warmup_s": warmup_s,
        "run_s": run_s,
        "run_s_all": times,
        "simulated_time_all": [b[1] for b in blocks],
        "ms_per_step": 1e3 * run_s / n_steps,
        "particle_steps_per_s": n * n_steps / run_s,
        "wall_per_simulated_s": run_s / (n_steps * dt),
        "peak_rss_mib": peak_self + peak_children,
        "peak_rss_self_mib": peak_self,
        "peak_rss_children_mib": peak_children,
        "finite": finite,
        "fluid_u_max": u_max,
        "method": method,
        "versions": {
            "pysph": pysph.__version__,
            "compyle": md.version("compyle"),
            "cython": md.version("cython"),
            "numpy": np.__version__,
        },
        "cpus": len(os.sched_getaffinity(0)),
        "omp_env": {k: v for k, v in os.environ.items() if k.startswith(omp_vars)},
        "loadavg_1min_start": load_start,
        "loadavg_1min_end": os.getloadavg()[0],
    }


def main(argv=None):
    """Parse the command line, run, print one JSON line."""
    t_start = time.perf_counter()
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dx", type=float, required=True, help="particle spacing [m]")
    p.add_argument("--steps", type=int, default=200, help="steps per timed block")
    p.add_argument("--repeats", type=int, default=3, help="timed blocks (best counts)")
    p.add_argument("--warmup", type=int, default=50, help="untimed steps before timing")
    p.add_argument("--openmp", action="store_true", help="compile and run with OpenMP")
    p.add_argument(
        "--threads",
        type=int,
        default=0,
        help="OpenMP threads (default: OpenMP's own default)",
    )
    p.add_argument(
        "--count-only",
        action="store_true",
        help="print particle counts for --dx and exit (no compile)",
    )
    args = p.parse_args(argv)
    if args.dx <= 0 or args.steps < 1 or args.repeats < 1 or args.warmup < 0:
        p.error("need --dx > 0, --steps >= 1, --repeats >= 1, --warmup >= 0")
    record = count_particles(args) if args.count_only else run(args, t_start)
    print(json.dumps(record))


if __name__ == "__main__":
    main()
