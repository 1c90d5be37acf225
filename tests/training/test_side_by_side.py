"""Several bundles adapted side by side: the cores they share, the bundles they write."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from sphere_jax.bundles import store
from sphere_jax.data import demo
from sphere_jax.training import adaptation, side_by_side
from sphere_jax.models import shipped


def test_core_shares_are_disjoint_until_there_are_too_few_cores():
    assert side_by_side.core_shares(2, [0, 1]) == [(0,), (1,)]
    shares = side_by_side.core_shares(3, range(16))
    assert sorted(c for s in shares for c in s) == list(range(16))
    assert [len(s) for s in shares] == [6, 5, 5]
    # more jobs than cores: each job may use every core (the OS shares them)
    assert side_by_side.core_shares(3, [4, 5]) == [(4, 5)] * 3
    assert side_by_side.core_shares(1) == [tuple(side_by_side.usable_cores())]


@pytest.mark.slow
def test_two_bundles_adapt_side_by_side_into_their_own_workdirs(tmp_path):
    """Compass and LEAD for a few steps each on two real scans (a synthetic pair without the
    data), each in its own process: both bundles written, each recording the two scans, each
    log starting from its bundle's validation loss."""
    (src, dst), _ = demo.fragment_pair()
    scans = []
    for name, points in (("a", src), ("b", dst)):
        scans.append(str(tmp_path / f"{name}.npy"))
        np.save(scans[-1], points)
    jobs = [(kind, shipped.bundle_path(kind), str(tmp_path / kind), None)
            for kind in ("compass", "lead")]
    adapted = side_by_side.adapt_side_by_side(jobs, ",".join(scans), steps=2, progress=False)
    assert adapted == [os.path.join(str(tmp_path / k), "bundle") for k in ("compass", "lead")]
    for kind, path in zip(("compass", "lead"), adapted):
        assert store.read_config(path).model == kind
        assert store.read_config(path).train.steps_done == 2
        with open(os.path.join(path, "training_data.json")) as f:
            assert sum(json.load(f)["folders"].values()) == 2       # the two scans, no more
        assert "(2 scans)" in open(os.path.join(path, "MODEL_CARD.md")).read()
        assert adaptation.outcome(path).startswith(f"{kind}: 2 steps, validation loss")


def test_a_failed_job_raises_its_error_after_the_others_end(tmp_path):
    """A refusal inside a job (here: no scans where the data root points) comes back to the
    caller as the project's own error, not a broken pool."""
    from sphere_jax import checks
    empty = tmp_path / "empty"
    empty.mkdir()
    jobs = [("lead", shipped.bundle_path("lead"), str(tmp_path / "lead"), None)]
    with pytest.raises(checks.SphereJaxError):
        side_by_side.adapt_side_by_side(jobs, str(empty), steps=1, progress=False)


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="reads /proc")
def test_a_job_ends_soon_after_its_parent_is_killed():
    """A parent that starts a job and is then killed (SIGKILL: nothing of it runs after) does
    not leave the job running: the job, asleep for a minute, is gone within seconds."""
    child = ("import sys, time; from sphere_jax.training import side_by_side; "
             "side_by_side.exit_with_parent(0.1); print('ready', flush=True); time.sleep(60)")
    parent = ("import subprocess, sys; "
              f"p = subprocess.Popen([sys.executable, '-c', {child!r}], stdout=sys.stdout); "
              "print(p.pid, flush=True); p.wait()")
    proc = subprocess.Popen([sys.executable, "-c", parent], stdout=subprocess.PIPE, text=True,
                            cwd=os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
    job = int(proc.stdout.readline())
    assert proc.stdout.readline().strip() == "ready"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and _alive(job):
        time.sleep(0.1)
    assert not _alive(job)


@pytest.mark.slow
def test_a_script_without_a_main_guard_gets_a_clear_error(tmp_path):
    """Spawned jobs import the calling script first; a script that adapts side by side at its
    top level would start jobs from inside a job, which Python refuses there: the caller gets
    the project's error naming the guard, not a bare broken pool."""
    script = tmp_path / "unguarded.py"
    jobs = [(k, shipped.bundle_path(k), str(tmp_path / k), None) for k in ("lead", "compass")]
    script.write_text("from sphere_jax.training import side_by_side\n"
                      f"side_by_side.adapt_side_by_side({jobs!r}, {str(tmp_path)!r}, steps=1, "
                      "progress=False)\n")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=600, cwd=os.path.dirname(os.path.dirname(os.path.dirname(
                             os.path.abspath(__file__)))))
    assert out.returncode != 0
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("sphere_jax.checks.SphereJaxError: an adaptation job's process ended "
                           "without a result"), out.stderr[-2000:]
    assert 'if __name__ == "__main__":' in last


def _alive(pid):
    """Whether ``pid`` runs (a zombie, ended but not reaped, counts as ended)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
