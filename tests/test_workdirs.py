"""One run per workdir: a second run is refused at once, naming the first; the lock goes with
the process that held it; workdirs that cannot be created or written are named."""
import os
import subprocess
import sys
import time

import pytest

from sphere_jax import checks, workdirs

HOLD = ("import sys, time; from sphere_jax import workdirs\n"
        "with workdirs.claimed(sys.argv[1], 'python -m experiments.train --config=lead:mid'):\n"
        "    print('held', flush=True); time.sleep(600)\n")


def test_a_second_run_is_refused_until_the_first_is_gone(tmp_path):
    first = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path)], stdout=subprocess.PIPE,
                             text=True, cwd=os.path.dirname(os.path.dirname(__file__)))
    try:
        assert first.stdout.readline().strip() == "held"
        t0 = time.perf_counter()
        with pytest.raises(workdirs.WorkdirBusy,
                           match=rf"in use by process {first.pid} on .*experiments.train "
                                 r"--config=lead:mid\), running since"):
            with workdirs.claimed(tmp_path):
                pass
        assert time.perf_counter() - t0 < 2.0
    finally:
        first.kill()                                  # kill -9: no clean-up of its own
        first.wait()
    with workdirs.claimed(tmp_path, "again") as w:    # the kernel released the lock
        assert w == str(tmp_path)
        with workdirs.claimed(tmp_path):              # the same run may claim it again
            pass


def test_unusable_workdirs_are_named(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(checks.ConfigError, match=r"--workdir .*file/w cannot be created"):
        workdirs.prepare(tmp_path / "file" / "w")
    if os.geteuid() != 0:                             # root writes anywhere
        locked = tmp_path / "ro"
        locked.mkdir(mode=0o500)
        with pytest.raises(checks.ConfigError, match="cannot be written"):
            workdirs.prepare(locked)
