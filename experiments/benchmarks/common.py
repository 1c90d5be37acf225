"""What every benchmark suite shares: timing, the machine line, the printed table."""
from __future__ import annotations

import os
import platform
import statistics
import time

import jax


def median_ms(fn, repeats):
    jax.block_until_ready(fn())                                      # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def machine_line():
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPU cores, "
            f"jax {jax.__version__} ({jax.default_backend()})")


def format_table(records):
    cols = list(dict.fromkeys(c for r in records for c in r))     # suites mix record kinds
    rows = [[str(r.get(c, "")) for c in cols] for r in records]
    widths = [max(len(c), *(len(row[i]) for row in rows)) for i, c in enumerate(cols)]
    line = lambda cells: "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths)) + " |"
    return "\n".join([line(cols), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
                     + [line(r) for r in rows])
