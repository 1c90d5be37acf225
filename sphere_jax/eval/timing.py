"""Wall time of a stretch of work, and how much of the machine other processes used meanwhile.

A description time measured while a training run shares the cores is not the method's own:
on 2 cores it can double. Each timed stretch therefore also records ``others``, the share of
the machine's core time spent by other processes while it ran (the busy time of every core
from Linux's ``/proc/stat``, less this process's own CPU time, over wall time × cores), so
that a table can say which of its times were measured alone. Where ``/proc/stat`` cannot be
read (macOS, Windows) ``others`` is None: unknown, not zero.
"""
from __future__ import annotations

import os
import time

PROC_STAT = "/proc/stat"
# /proc/stat's first line: cpu user nice system idle iowait irq softirq steal guest guest_nice.
# guest time is already counted in user; idle and iowait are the cores doing nothing.
_BUSY = (0, 1, 2, 5, 6, 7)


def machine_busy_s(path: str = PROC_STAT) -> float | None:
    """Seconds of CPU time all cores have spent busy since boot (None: not readable)."""
    try:
        with open(path) as f:
            fields = f.readline().split()
        ticks = [int(fields[1 + i]) for i in _BUSY]
    except (OSError, ValueError, IndexError):
        return None
    return sum(ticks) / os.sysconf("SC_CLK_TCK")


def own_cpu_s() -> float:
    """CPU seconds of this process, all its threads, user and system."""
    t = os.times()
    return t.user + t.system


def others_share(busy_s: float, own_s: float, wall_s: float, cores: int) -> float:
    """Share (0 to 1) of ``cores`` × ``wall_s`` core-seconds that other processes were busy,
    given the machine's busy seconds and this process's over the same stretch."""
    if wall_s <= 0 or cores < 1:
        return 0.0
    return min(1.0, max(0.0, (busy_s - own_s) / (wall_s * cores)))


class Stopwatch:
    """``with Stopwatch() as w: ...`` then ``w.seconds`` (wall time) and ``w.others``
    (:func:`others_share`, or None where the machine's busy time is unknown)."""

    def __init__(self, stat_path: str = PROC_STAT):
        self._path = stat_path
        self.seconds = 0.0
        self.others: float | None = None

    def __enter__(self):
        self._start = (time.perf_counter(), own_cpu_s(), machine_busy_s(self._path))
        return self

    def __exit__(self, *exc):
        wall0, own0, busy0 = self._start
        self.seconds = time.perf_counter() - wall0
        busy1 = machine_busy_s(self._path)
        if busy0 is not None and busy1 is not None:
            self.others = others_share(busy1 - busy0, own_cpu_s() - own0, self.seconds,
                                       os.cpu_count() or 1)
        return False
