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

Inference runs a jitted function over many rows in fixed-size chunks (:func:`run_chunked`,
:func:`stream_chunked`), several at once on a CPU and split across the local devices.
"""
from __future__ import annotations

import atexit
import collections
import concurrent.futures
import os
import sys
import threading
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from sphere_jax import checks

AXIS = "batch"
DEFAULT_CHUNK = 256         # patches per call when neither the caller nor the bundle says
PEER_TIMEOUT_S = 60.0       # a silent peer of a multi-process run is given up after this
PEER_LOST_EXIT = 75         # exit status then (EX_TEMPFAIL: run the same command again)


def initialize(coordinator: str | None = None, num_processes: int | None = None,
               process_id: int | None = None, peer_timeout_s: float = PEER_TIMEOUT_S):
    """Join a multi-host run. With no arguments JAX detects Slurm, Open MPI and Cloud TPU
    launches itself; otherwise all three are needed (as for ``jax.distributed.initialize``).

    A process that dies (OOM-killed, preempted) stops the others within ``peer_timeout_s``
    seconds, each with one last line naming the lost process (:class:`PeerWatch`), instead of
    JAX's abort dump; the same command then resumes from the last checkpoint."""
    given = [a is not None for a in (coordinator, num_processes, process_id)]
    if any(given) and not all(given):
        raise ValueError("coordinator, num_processes and process_id go together: give all "
                         "three or none (auto-detection on Slurm, Open MPI or TPU)")
    peer_timeout_s = checks.positive(peer_timeout_s, "peer_timeout_s")
    # JAX's own heartbeat aborts the process with a C++ fatal error: let the watch, which
    # can say what happened, come first.
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes,
                               process_id=process_id,
                               heartbeat_timeout_seconds=int(max(100, 4 * peer_timeout_s)))
    if jax.process_count() > 1:
        PeerWatch(peer_timeout_s).start()


class PeerWatch(threading.Thread):
    """Every process of a ``jax.distributed`` run counts up its own key in the coordination
    service's key-value store every ``timeout_s / 10`` seconds and reads the others'. A peer
    whose count has not moved for ``timeout_s`` seconds — or a coordinator that no longer
    answers — ends this process with exit status :data:`PEER_LOST_EXIT` and one line naming
    the lost process. A process that ends normally says so first (``atexit``), so the others
    do not mistake it for a lost one. Blocked collectives do not stop the watch: it is a
    thread of its own, and XLA releases the GIL while it runs.

    A dead peer usually surfaces first as an error in this process's main thread (a
    collective's connection reset): :meth:`start` hooks ``sys.excepthook`` so that, after the
    traceback, the process waits for the watch's verdict instead of running JAX's shutdown
    barrier, which would wait for the dead peer and then abort."""

    def __init__(self, timeout_s: float, client=None, me: int | None = None,
                 processes: int | None = None, exit_fn=None):
        super().__init__(name="sphere_jax-peer-watch", daemon=True)
        from jax._src import distributed
        self.client = client or distributed.global_state.client
        self.me = jax.process_index() if me is None else me
        self.n = jax.process_count() if processes is None else processes
        self.timeout_s, self.interval_s = float(timeout_s), max(0.2, float(timeout_s) / 10)
        self.exit_fn = exit_fn or os._exit
        self.stopped, self.stopped_by_peer = threading.Event(), threading.Event()
        atexit.register(self.finish)

    def start(self):
        previous = sys.excepthook

        def excepthook(kind, value, tb):
            previous(kind, value, tb)
            if not issubclass(kind, KeyboardInterrupt) and not self.stopped.is_set():
                self.stopped_by_peer.wait(self.timeout_s + 3 * self.interval_s)

        sys.excepthook = excepthook
        super().start()

    def _key(self, what, p):
        return f"sphere_jax/peer_watch/{what}/{p}"

    def _get(self, what, p):
        """A peer's value, None while it has not written one."""
        try:
            return self.client.key_value_try_get(self._key(what, p))
        except Exception as e:               # noqa: BLE001 - JAX raises NOT_FOUND for a new key
            if "NOT_FOUND" in str(e):
                return None
            raise

    def finish(self):
        """This process ends normally: stop beating and tell the others."""
        if not self.stopped.is_set():
            self.stopped.set()
            try:
                self.client.key_value_set(self._key("done", self.me), "1", allow_overwrite=True)
            except Exception:               # the coordinator has gone already: nothing to tell
                pass

    def run(self):
        count, seen = 0, {}
        while not self.stopped.wait(self.interval_s if count else 0):
            count += 1
            now = time.monotonic()
            try:
                self.client.key_value_set(self._key("alive", self.me), str(count),
                                          allow_overwrite=True)
                for p in range(self.n):
                    if p == self.me or self._get("done", p):
                        continue
                    beat = self._get("alive", p)
                    if p not in seen or seen[p][0] != beat:
                        seen[p] = (beat, now)
                    elif now - seen[p][1] > self.timeout_s:
                        return self._lost(f"process {p} of {self.n} stopped answering "
                                          f"{now - seen[p][1]:.0f} s ago (killed, preempted "
                                          f"or out of memory)")
            except Exception as e:               # noqa: BLE001 - any RPC failure means the same
                if self.stopped.is_set():
                    return
                return self._lost(f"the coordinator (process 0 of {self.n}) no longer answers "
                                  f"({type(e).__name__})")

    def _lost(self, what):
        if self.stopped.is_set():
            return
        sys.stderr.write(f"\nsphere_jax: {what}; process {self.me} stops here. Run the same "
                         f"command again on every process to resume from the last checkpoint "
                         f"(finished scenes of an evaluation are kept).\n")
        sys.stderr.flush()
        self.stopped_by_peer.set()
        self.exit_fn(PEER_LOST_EXIT)


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


def in_slices(fn, size: int | None):
    """``fn`` over the rows of its arguments (arrays ``[K, ...]`` or None) in slices of ``size``
    rows one after the other inside the traced call (``lax.map``), results concatenated. For a
    jitted network over a chunk of patches on one CPU: the same values with one slice's
    intermediates at a time, which stay in the cache and, allocated once per call, are
    page-faulted once per call. ``fn`` alone when ``size`` is None, K is not a larger multiple
    of it, or the chunk runs on an accelerator or across several devices (where one step over
    the whole chunk is what keeps them busy, and a loop over a sharded axis would not split)."""
    if size is None:
        return fn

    def sliced(*args):
        k = next(a.shape[0] for a in args if a is not None)
        if k <= size or k % size or jax.default_backend() != "cpu" \
                or jax.local_device_count() > 1:
            return fn(*args)
        split = lambda a: a.reshape((k // size, size) + a.shape[1:])
        out = jax.lax.map(lambda a: fn(*a), jax.tree.map(split, args))
        return jax.tree.map(lambda o: o.reshape((k,) + o.shape[2:]), out)
    sliced.whole = fn                # for XLA's flop count, which sees one slice of a loop
    return sliced


def run_chunked(fn, x, chunk=None, workers=None):
    """``fn`` over the rows of ``x`` in chunks (:func:`stream_chunked`)."""
    x = np.asarray(x)
    return stream_chunked(fn, lambda a, b: (x[a:b],), len(x), chunk, workers)


def stream_chunked(fn, make, n, chunk=None, workers=None):
    """``fn(*make(a, b))`` over rows ``0..n`` in chunks of a fixed size (the last one padded),
    so a jitted ``fn`` compiles once whatever ``n``; one thread prepares the next chunk's
    inputs (in order) while ``workers`` chunks run (default :func:`default_workers`), so at
    most ``workers + 1`` chunks exist at a time.

    Concurrent chunks are what uses a multi-core CPU here: XLA runs the loops of the fused
    inference path (:mod:`~sphere_jax.spherical.fused`) on one thread, so one chunk at a time
    keeps one core busy (LEAD 'paper' encoder on 2 cores: 19 ms per patch alone, 12 with two
    chunks).
    Each chunk in flight holds its own intermediates, so memory grows with ``workers``.
    """
    chunk = checks.positive(DEFAULT_CHUNK if chunk is None else chunk, "chunk", integer=True)
    workers = checks.positive(default_workers() if workers is None else workers, "workers",
                              integer=True)
    if n == 0:
        return np.zeros((0,))
    rows_on = chunk_sharding()
    if rows_on is not None:                  # every device takes an equal block of each chunk
        chunk = -(-chunk // rows_on.mesh.size) * rows_on.mesh.size
    starts = list(range(0, n, chunk))

    def prepare(a):
        parts = make(a, min(a + chunk, n))
        rows = len(parts[0])
        pad = chunk - rows
        if pad:
            parts = tuple(np.concatenate([p, np.repeat(p[-1:], pad, 0)]) for p in parts)
        return parts, rows

    def compute(parts, rows):
        put = jnp.asarray if rows_on is None else lambda p: jax.device_put(p, rows_on)
        return np.asarray(fn(*(put(p) for p in parts)))[:rows]

    out, running = [], collections.deque()
    workers = min(len(starts), workers)
    with concurrent.futures.ThreadPoolExecutor(1) as prep, \
            concurrent.futures.ThreadPoolExecutor(workers) as pool:
        ahead = prep.submit(prepare, starts[0])
        for j in range(len(starts)):
            parts, rows = ahead.result()
            if j + 1 < len(starts):
                ahead = prep.submit(prepare, starts[j + 1])
            running.append(pool.submit(compute, parts, rows))
            if len(running) >= workers:
                out.append(running.popleft().result())
        out.extend(f.result() for f in running)
    return np.concatenate(out)


def chunk_sharding():
    """With more than one local device (GPUs, TPU cores, or CPU host devices forced by
    ``XLA_FLAGS``): chunks split on their first axis across all of them, so the jitted
    network runs on every device at once (one SPMD program, :mod:`sphere_jax.parallel`'s
    axis); None with one device. Only this process's devices: in a multi-process run each
    process describes its own scans."""
    devices = jax.local_devices()
    if len(devices) < 2:
        return None
    return jax.sharding.NamedSharding(jax.sharding.Mesh(np.array(devices), (AXIS,)),
                                      jax.sharding.PartitionSpec(AXIS))


def default_workers() -> int:
    """Chunks run at a time by :func:`run_chunked`: on a CPU backend one per core this process
    may use, at most 4 (each holds its chunk's intermediates: about 0.7 GB for LEAD 'paper' at
    256 patches); on an accelerator 1, since its own parallelism runs each chunk already."""
    if jax.default_backend() != "cpu":
        return 1
    return max(1, min(4, len(os.sched_getaffinity(0))))
