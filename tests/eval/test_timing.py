"""The stopwatch's share of the cores other processes used: its arithmetic, a real competitor,
and 'unknown' where the machine's busy time cannot be read."""
import multiprocessing
import os
import time

import pytest

from sphere_jax.eval import timing


def _spin(seconds):
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def test_others_share_is_the_busy_time_not_ours_over_all_cores():
    assert timing.others_share(busy_s=3.0, own_s=1.0, wall_s=2.0, cores=2) == pytest.approx(0.5)
    assert timing.others_share(busy_s=1.0, own_s=1.0, wall_s=2.0, cores=2) == 0.0
    # Clock ticks can put our time a hair above the machine's: never below 0 or above 1.
    assert timing.others_share(busy_s=0.9, own_s=1.0, wall_s=1.0, cores=2) == 0.0
    assert timing.others_share(busy_s=9.0, own_s=0.0, wall_s=1.0, cores=2) == 1.0


@pytest.mark.skipif(timing.machine_busy_s() is None, reason="no /proc/stat")
def test_a_process_spinning_beside_the_timed_work_is_seen():
    child = multiprocessing.get_context("spawn").Process(target=_spin, args=(3.0,))
    child.start()
    time.sleep(1.0)                              # the child is up and spinning
    with timing.Stopwatch() as watch:
        time.sleep(1.0)                          # we use no CPU; one core is busy elsewhere
    child.join()
    cores = os.cpu_count()
    assert watch.seconds == pytest.approx(1.0, abs=0.2)
    assert watch.others >= 0.7 / cores, watch.others


def test_our_own_work_is_not_counted_as_others(monkeypatch):
    # A machine that runs nothing but this process: its busy time is our CPU time.
    monkeypatch.setattr(timing, "machine_busy_s", lambda path: timing.own_cpu_s())
    with timing.Stopwatch() as watch:
        _spin(0.5)
    assert watch.seconds >= 0.5 and watch.others == 0.0


def test_an_unreadable_stat_file_means_unknown(tmp_path):
    with timing.Stopwatch(stat_path=str(tmp_path / "missing")) as watch:
        pass
    assert watch.others is None and watch.seconds >= 0
    (tmp_path / "stat").write_text("not a stat file\n")
    assert timing.machine_busy_s(str(tmp_path / "stat")) is None
