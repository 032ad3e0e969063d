"""Devices: the one-axis mesh a batch of members is split over, results brought
back to the host (from every process of a multi-process run), joining a
multi-process run, and one run's particle arrays split over devices."""

import math

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

# The name of the member axis of the meshes that `member_mesh` makes.
MEMBERS = "members"


def member_mesh(mesh: Mesh | None = None, devices: int | None = None) -> Mesh:
    """The one-axis mesh a batch of members is split over: `mesh` itself (checked),
    or the first `devices` of `jax.devices()` (None: all of them, over every
    process of a multi-process run).

    Raises:
        ValueError: for a mesh of more than one axis, or more devices than exist
            (naming the setting and what exists).
    """
    if mesh is not None:
        if devices is not None:
            raise ValueError("Give `mesh` or `devices`, not both.")
        if not isinstance(mesh, Mesh):
            raise ValueError(
                f"mesh must be a jax.sharding.Mesh, got {type(mesh).__name__}."
            )
        if len(mesh.axis_names) != 1:
            raise ValueError(
                "mesh must have one axis (the members are split along it), got "
                f"axes {tuple(mesh.axis_names)}."
            )
        return mesh
    available = jax.devices()
    if devices is None:
        devices = len(available)
    if isinstance(devices, bool) or not isinstance(devices, (int, np.integer)):
        raise ValueError(f"devices must be a whole number, got {devices!r}.")
    if not 1 <= devices <= len(available):
        raise ValueError(
            f"devices={devices} asked for, but {len(available)} "
            f"{available[0].platform.upper()} device(s) exist "
            f"({', '.join(str(d) for d in available[:8])}"
            f"{', ...' if len(available) > 8 else ''}); give at most "
            f"{len(available)} (for several CPU devices set XLA_FLAGS="
            "--xla_force_host_platform_device_count=N before JAX starts)."
        )
    return Mesh(np.asarray(available[:devices]), (MEMBERS,))


def _put(value: np.ndarray, sharding: NamedSharding) -> jax.Array:
    """`value` (the same on every process) laid out by `sharding`."""
    if sharding.is_fully_addressable:
        return jax.device_put(value, sharding)
    return jax.make_array_from_callback(
        value.shape, sharding, lambda index: value[index]
    )


def to_host(tree):
    """`tree` as numpy arrays, the pieces held by other processes gathered in (every
    process gets the whole)."""

    def fetch(x):
        if isinstance(x, jax.Array) and not x.is_fully_addressable:
            from jax.experimental import multihost_utils

            return np.asarray(multihost_utils.process_allgather(x, tiled=True))
        return np.asarray(x)

    return jax.tree.map(fetch, tree)


def start_processes(
    coordinator: str, num_processes: int, process_id: int, timeout: float = 60.0
) -> None:
    """Join a run of `num_processes` processes (`jax.distributed.initialize`), this
    one being `process_id`, with process 0 at `coordinator` ("host:port"); on CPU
    the processes exchange data by Gloo. Call before anything else uses JAX.

    The wait is bounded: a process other than 0 first waits up to `timeout`
    for the coordinator to listen, and is refused with a ConnectionError if it
    never does. Once connected, JAX's own runtime waits up to `timeout` for the
    rest and ends the process (abort, with a DEADLINE_EXCEEDED message) if they
    do not all join.

    Raises:
        ConnectionError: if the coordinator does not answer within `timeout`
            seconds (naming the coordinator and the timeout).
    """
    import os

    if int(process_id) != 0:
        _wait_for(coordinator, timeout, process_id, num_processes)
    platforms = os.environ.get("JAX_PLATFORMS", "")
    if platforms in ("", "cpu"):
        # Collectives between CPU processes (the default implementation has none).
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    try:
        jax.distributed.initialize(
            coordinator_address=coordinator,
            num_processes=int(num_processes),
            process_id=int(process_id),
            initialization_timeout=max(1, math.ceil(timeout)),
        )
    except Exception as e:  # noqa: BLE001 - JAX raises several types here
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ConnectionError(
            f"Process {process_id} of {num_processes} could not join the run at "
            f"--coordinator {coordinator} within --timeout {timeout:g} s ({first}). "
            "Start every process with the same --coordinator (process 0's host and "
            "a free port) and --num-processes."
        ) from None


def _wait_for(coordinator: str, timeout: float, process_id, num_processes) -> None:
    """Wait until something listens at `coordinator` ("host:port"), at most
    `timeout` seconds (ConnectionError naming both)."""
    import socket
    import time

    host, _, port = coordinator.rpartition(":")
    try:
        port = int(port)
    except ValueError:
        raise ValueError(
            f"--coordinator must be HOST:PORT, got {coordinator!r}."
        ) from None
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host or "localhost", port), timeout=1.0):
                return
        except OSError as e:
            if time.monotonic() >= deadline:
                raise ConnectionError(
                    f"Process {process_id} of {num_processes} could not join the run "
                    f"at --coordinator {coordinator} within --timeout {timeout:g} s "
                    f"(nothing answers there: {e.strerror or e}). Start process 0 "
                    "with the same --coordinator (its host and a free port) and "
                    "--num-processes."
                ) from None
            time.sleep(0.2)


# The name of the particle axis of `shard_particles`' meshes.
PARTICLES = "particles"


def shard_particles(state, mesh: Mesh | None = None, devices: int | None = None):
    """`state` with its per-particle arrays (leading axis the capacity n) split in
    equal blocks of consecutive particles over the devices of a one-axis `mesh`
    (default: the first `devices` of `jax.devices()`, all if None), the rest
    copied to every device. `simulate` then runs one program partitioned by XLA
    over those devices (`benchmarks/sharded_run.py` measures what that costs).

    Raises:
        ValueError: for a mesh of more than one axis, more devices than exist, or
            a capacity that the device count does not divide (naming both).
    """
    if mesh is None:
        mesh = member_mesh(devices=devices)
        mesh = Mesh(mesh.devices, (PARTICLES,))
    else:
        mesh = member_mesh(mesh)
    n = int(state.position.shape[0])
    count = int(mesh.devices.size)
    if n % count:
        raise ValueError(
            f"The state's capacity {n} is not a multiple of the {count} devices; "
            "shard it over a device count that divides it, or change the scene's "
            "size (spacing) by a particle or two."
        )
    axis = mesh.axis_names[0]
    split = NamedSharding(mesh, PartitionSpec(axis))
    whole = NamedSharding(mesh, PartitionSpec())

    def place(x):
        if not isinstance(x, (jax.Array, np.ndarray)):
            return x
        per_particle = np.ndim(x) >= 1 and np.shape(x)[0] == n
        return _put(np.asarray(x), split if per_particle else whole)

    return jax.tree.map(place, state)
