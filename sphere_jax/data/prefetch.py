"""Batches built ahead of the train step in a background thread.

Patch extraction is numpy and scikit-learn work that releases the GIL for most of its time, so a
thread overlaps it with the jitted step. The order is the step order (each batch is a function
of the seed and its step), so prefetching changes nothing in what is trained on.
"""
from __future__ import annotations

import queue
import threading
import time
from typing import Callable, Iterable

_DONE = object()


class Prefetch:
    """Iterate ``(step, make(step))`` for ``steps`` with up to ``depth`` batches made ahead.

    :attr:`wait_s` accumulates the time the consumer spent waiting for a batch (the data stall
    of the loop). An exception in ``make`` is raised in the consumer at the step it happened;
    :meth:`close` (or leaving a ``with`` block) stops the thread.
    """

    def __init__(self, make: Callable[[int], object], steps: Iterable[int], depth: int = 2):
        if depth < 1:
            raise ValueError(f"depth must be >= 1, got {depth}")
        self.wait_s = 0.0
        self._queue: queue.Queue = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._fill, args=(make, list(steps)),
                                        daemon=True, name="sphere_jax-prefetch")
        self._thread.start()

    def _put(self, item):
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _fill(self, make, steps):
        for step in steps:
            try:
                item = (step, make(step), None)
            except BaseException as e:           # handed to the consumer, raised there
                self._put((step, None, e))
                return
            if not self._put(item):
                return
        self._put(_DONE)

    def __iter__(self):
        while True:
            t0 = time.perf_counter()
            item = self._queue.get()
            self.wait_s += time.perf_counter() - t0
            if item is _DONE:
                return
            step, batch, error = item
            if error is not None:
                raise error
            yield step, batch

    def close(self):
        self._stop.set()
        self._thread.join(timeout=5)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
