"""Evaluations split over processes started with jax.distributed: two local processes give
the tables one process gives, written once, by process 0."""
import pytest
import os
import socket
import subprocess
import sys

from sphere_jax.eval.report import TIMING_COLUMNS

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ARGS = ["-m", "experiments.evaluate", "--config=eval_registration:tiny",
        "--config.methods=fpfh,shot"]


def _port():
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_two_processes_write_the_tables_of_one(tmp_path):
    single = subprocess.run([sys.executable, *ARGS, f"--workdir={tmp_path / 'one'}"], cwd=REPO,
                            capture_output=True, text=True, timeout=600)
    assert single.returncode == 0, single.stderr[-2000:]
    port = _port()
    procs = [subprocess.Popen([sys.executable, *ARGS, f"--workdir={tmp_path / 'two'}",
                               f"--coordinator=localhost:{port}", "--num_processes=2",
                               f"--process_id={i}"], cwd=REPO, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for i in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    assert "Registration benchmark" in outs[0][0] and "Registration benchmark" not in outs[1][0]
    one = (tmp_path / "one" / "results.csv").read_text().splitlines()
    two = (tmp_path / "two" / "results.csv").read_text().splitlines()
    drop = lambda lines: [",".join(c for k, c in enumerate(ln.split(","))     # timings differ
                                   if k not in timing) for ln in lines]
    timing = [k for k, c in enumerate(one[0].split(",")) if c in TIMING_COLUMNS]
    assert len(one) >= 5 and drop(one) == drop(two)        # 2 scenes × 2 methods + header
    assert sorted(os.listdir(tmp_path / "two" / "processes")) == ["registration_0.pkl",
                                                                 "registration_1.pkl"]
