"""Evaluations across processes started with ``jax.distributed`` (JAX's own multi-process
runtime, :func:`sphere_jax.parallel.initialize`; no scheduler of ours).

Each process takes every ``process_count``-th scene, starting at its ``process_index``
(:func:`share`), evaluates them, and hands its results to :func:`gather`: they go to
``workdir/processes/`` as one pickle per process, the processes meet at a barrier, and
process 0 gets every result back in the scenes' order and writes the tables. A single process
(the usual case) shares nothing and writes nothing extra.
"""
from __future__ import annotations

import os
import pickle

import jax

from sphere_jax import files


def share(items) -> list:
    """``[(index, item)]`` of this process's items: every ``process_count``-th one."""
    n, me = jax.process_count(), jax.process_index()
    return [(k, item) for k, item in enumerate(items) if k % n == me]


def is_writer() -> bool:
    """Whether this process writes the tables (process 0)."""
    return jax.process_index() == 0


def gather(indexed_results, workdir, name):
    """Every process's ``[(index, [results])]`` on process 0, as one list of results in index
    order; the other processes get None. Blocks until every process has called it."""
    if jax.process_count() == 1:
        return [r for _, rs in sorted(indexed_results, key=lambda x: x[0]) for r in rs]
    from jax.experimental import multihost_utils
    folder = os.path.join(workdir, "processes")
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, f"{name}_{jax.process_index()}.pkl")
    files.atomic_write(path, pickle.dumps(indexed_results))
    multihost_utils.sync_global_devices(f"sphere_jax:{name}:written")
    merged = None
    if is_writer():
        merged = []
        for p in range(jax.process_count()):
            with open(os.path.join(folder, f"{name}_{p}.pkl"), "rb") as f:
                merged += pickle.load(f)
        merged = [r for _, rs in sorted(merged, key=lambda x: x[0]) for r in rs]
    multihost_utils.sync_global_devices(f"sphere_jax:{name}:read")
    return merged
