"""Data parallelism with JAX's own SPMD: one mesh axis over the devices of every host.

Batches are split on their first axis across the mesh (each device gets a contiguous block of
rows); parameters, optimiser state and batch statistics are replicated. The train step runs
under ``jax.shard_map``: every device computes its block's loss and gradients, the gradients
and metrics are averaged with ``pmean``, and batch norm averages its moments over the axis
(``axis_name=AXIS`` in the models), so the step is that of the whole batch on one device up to
float round-off.

Several hosts: call :func:`initialize` (``jax.distributed.initialize``) before any other JAX
call; every host then runs the same program, builds the same deterministic batch and hands its
own rows to the mesh (:func:`shard_batch`).
"""
from __future__ import annotations

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

AXIS = "batch"


def initialize(coordinator: str | None = None, num_processes: int | None = None,
               process_id: int | None = None):
    """Join a multi-host run. With no arguments JAX detects Slurm, Open MPI and Cloud TPU
    launches itself; otherwise all three are needed (as for ``jax.distributed.initialize``)."""
    given = [a is not None for a in (coordinator, num_processes, process_id)]
    if any(given) and not all(given):
        raise ValueError("coordinator, num_processes and process_id go together: give all "
                         "three or none (auto-detection on Slurm, Open MPI or TPU)")
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes,
                               process_id=process_id)


def make_mesh(devices_per_host: int | None = None) -> Mesh:
    """A one-axis mesh (:data:`AXIS`) over the first ``devices_per_host`` local devices of each
    host (default and 0: all of them), hosts in process order."""
    local = jax.local_device_count()
    n = devices_per_host or local
    if not isinstance(n, (int, np.integer)) or not 1 <= n <= local:
        raise ValueError(f"train.devices must be between 1 and the {local} local device(s) "
                         f"(0: all), got {devices_per_host!r}")
    devices = []
    for p in range(jax.process_count()):
        devices += sorted((d for d in jax.devices() if d.process_index == p),
                          key=lambda d: d.id)[:n]
    return Mesh(np.array(devices), (AXIS,))


def check_batch_size(batch_size: int, mesh: Mesh):
    if batch_size % mesh.size:
        raise ValueError(f"train.batch_size={batch_size} must be a multiple of the "
                         f"{mesh.size} devices it is split across (train.devices)")


def replicated(mesh: Mesh) -> NamedSharding:
    return NamedSharding(mesh, PartitionSpec())


def split(mesh: Mesh) -> NamedSharding:
    return NamedSharding(mesh, PartitionSpec(AXIS))


def replicate(tree, mesh: Mesh):
    """Every leaf of ``tree`` on every device of the mesh."""
    return jax.device_put(tree, replicated(mesh))


def shard_batch(batch: dict, mesh: Mesh) -> dict:
    """Numpy arrays ``[B, ...]`` (the same on every host) -> global arrays split on their first
    axis across the mesh; each host transfers only the rows of its own devices."""
    sharding = split(mesh)
    if jax.process_count() == 1:
        return jax.device_put(batch, sharding)
    hosts, me = jax.process_count(), jax.process_index()

    def put(x):
        x = np.asarray(x)
        rows = x.shape[0] // hosts
        return jax.make_array_from_process_local_data(sharding, x[me * rows:(me + 1) * rows],
                                                      x.shape)
    return {k: put(v) for k, v in batch.items()}
