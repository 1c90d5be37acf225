"""Data-parallel training over a mesh of host devices (two CPU devices, forced through
XLA_FLAGS in child processes: the device count is fixed when JAX starts)."""
import json
import os
import shutil
import socket
import subprocess
import sys
import time

import jax
import numpy as np
import pytest

from sphere_jax import parallel
from tests.test_training import tiny

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _frame_parameters(params):
    """Every parameter but the last batch norm's bias, as one float64 vector. The soft-argmax
    ignores a constant shift of the map, so that bias's gradient is zero but for round-off,
    whose sign Adam turns into steps of ±learning rate (measured: 1.9 relative after one step
    between device counts, while every other parameter agreed to 1e-7); it has no effect on
    the frames."""
    leaves = jax.tree_util.tree_leaves_with_path(params)
    keep = [np.ravel(x) for p, x in leaves
            if not ("GridBatchNorm_3" in jax.tree_util.keystr(p) and "bias" in
                    jax.tree_util.keystr(p))]
    return np.concatenate(keep).astype(np.float64)


def child_main():
    """In the child: ROOT WORKDIR DEVICES STEPS [COORDINATOR PROCESSES ID [PEER_TIMEOUT_S]] ->
    WORKDIR/params.npy (in a multi-host run, WORKDIR/params_ID.npy)."""
    import pathlib
    from sphere_jax import training
    root, workdir, devices, steps = sys.argv[1:5]
    out = "params.npy"
    if len(sys.argv) > 5:
        coordinator, processes, pid = sys.argv[5:8]
        timeout = float(sys.argv[8]) if len(sys.argv) > 8 else parallel.PEER_TIMEOUT_S
        parallel.initialize(coordinator, int(processes), int(pid), timeout)
        out = f"params_{pid}.npy"
    c = tiny("compass", pathlib.Path(root), steps=int(steps), checkpoint_every=2,
             eval_every=100, log_every=1)
    c.train.devices = int(devices)
    state, _ = training.train_and_evaluate(c, workdir, progress=False)
    np.save(os.path.join(workdir, out), _frame_parameters(state["params"]))


def _child(root, workdir, devices, steps, *hosts, host_devices=2):
    env = {**os.environ,
           "XLA_FLAGS": f"--xla_force_host_platform_device_count={host_devices}"}
    code = "from tests.test_parallel import child_main; child_main()"
    return subprocess.Popen([sys.executable, "-c", code, str(root), str(workdir), str(devices),
                             str(steps), *map(str, hosts)], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _train(root, workdir, devices, steps):
    """Train the tiny Compass config in a child process that has two host devices."""
    proc = _child(root, workdir, devices, steps)
    _, err = proc.communicate()
    assert proc.returncode == 0, err[-3000:]
    return np.load(os.path.join(workdir, "params.npy"))


@pytest.fixture(scope="module")
def two_devices_4_steps(small_root_parallel, tmp_path_factory):
    """``(workdir, params)`` of 4 steps on two devices: the reference of the two-host run,
    and the interrupted half of the resumed one (a child process less for each)."""
    workdir = tmp_path_factory.mktemp("two_devices_4_steps") / "run"
    return workdir, _train(small_root_parallel, workdir, 2, 4)


def test_two_hosts_equal_one_host_with_two_devices(small_root_parallel, two_devices_4_steps,
                                                   tmp_path):
    """Two processes of one CPU device each, joined by jax.distributed on localhost, sharing
    a workdir: the same parameters, bitwise, as one process with two devices."""
    with socket.socket() as s:                       # a free port for the coordinator
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    hosts = [_child(small_root_parallel, tmp_path / "hosts", 1, 4, f"localhost:{port}", 2, i,
                    host_devices=1) for i in range(2)]
    for proc in hosts:
        _, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err[-3000:]
    first, second = (np.load(tmp_path / "hosts" / f"params_{i}.npy") for i in range(2))
    np.testing.assert_array_equal(first, second)
    one_host, one_host_params = two_devices_4_steps
    np.testing.assert_array_equal(first, one_host_params)
    # Bundles trained on two devices (or hosts) load in this one-device process.
    from sphere_jax.bundles import inference
    for run in (tmp_path / "hosts", one_host):
        loaded = inference.load_bundle(run / "bundle")
        assert np.isfinite(_frame_parameters(loaded.variables["params"])).all()
    assert len((tmp_path / "hosts" / "metrics.jsonl").read_text().splitlines()) == 4


def _free_port():
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def test_a_killed_host_stops_the_other_and_the_same_command_resumes(small_root_parallel,
                                                                    tmp_path):
    """kill -9 of one of two processes: the survivor stops within the peer timeout (not by
    JAX's abort), its last line naming the lost process; the same command on both then
    resumes from the last checkpoint and finishes."""
    work, steps, timeout = tmp_path / "hosts", 60, 10
    start = lambda port: [_child(small_root_parallel, work, 1, steps, f"localhost:{port}", 2,
                                 i, timeout, host_devices=1) for i in range(2)]
    hosts = start(_free_port())
    deadline = time.monotonic() + 300
    while not (work / "checkpoints" / "4").is_dir():
        assert time.monotonic() < deadline and all(h.poll() is None for h in hosts), \
            hosts[0].stderr.read()[-3000:] if hosts[0].poll() is not None else "no checkpoint"
        time.sleep(0.2)
    hosts[1].kill()
    killed = time.monotonic()
    _, err = hosts[0].communicate(timeout=180)
    took = time.monotonic() - killed
    hosts[1].communicate()
    print(f"survivor stopped {took:.1f} s after the kill")
    assert hosts[0].returncode == parallel.PEER_LOST_EXIT, err[-3000:]
    assert took < timeout + 20
    last = err.strip().splitlines()[-1]
    assert "process 1 of 2 stopped answering" in last and "same command again" in last, last
    again = start(_free_port())
    for proc in again:
        _, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err[-3000:]
    logged = [json.loads(line)["step"] for line in
              (work / "metrics.jsonl").read_text().splitlines()]
    assert logged == list(range(1, steps + 1))            # resumed, each step logged once
    assert (work / "bundle" / "config.json").is_file()


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_device_counts_agree_and_runs_repeat_bitwise(small_root_parallel, two_devices_4_steps,
                                                    tmp_path):
    one = _train(small_root_parallel, tmp_path / "one", 1, 10)
    two = _train(small_root_parallel, tmp_path / "two", 2, 10)
    again = _train(small_root_parallel, tmp_path / "again", 2, 10)
    np.testing.assert_array_equal(two, again)
    # One device and two sum the batch in different orders; ten Adam steps carry that
    # round-off to under 1e-6 on some CPUs, 4e-6 on others; ten steps move 1e-3 or more.
    assert _rel(two, one) <= 1e-5
    # Interrupted after 4 steps on two devices (a copy of that run), resumed on one.
    interrupted, four_steps = two_devices_4_steps
    shutil.copytree(interrupted, tmp_path / "resumed")
    resumed = _train(small_root_parallel, tmp_path / "resumed", 1, 10)
    assert _rel(resumed, one) <= 1e-5
    assert _rel(one, four_steps) > 1e-3                # 10 steps are not 4: the runs trained


@pytest.fixture(scope="module")
def small_root_parallel(tmp_path_factory):
    from sphere_jax.data.generators import synthetic
    from tests.data.generators.test_synthetic import SMALL
    root = tmp_path_factory.mktemp("parallel_data")
    synthetic.make_all(str(root), seed=5, n_scenes=1, **SMALL)
    return root


def test_mesh_and_batch_checks_name_the_setting():
    with pytest.raises(ValueError, match="train.devices"):
        parallel.make_mesh(jax.local_device_count() + 1)
    mesh = parallel.make_mesh()
    assert mesh.size == jax.device_count() and mesh.axis_names == (parallel.AXIS,)
    if mesh.size > 1:
        with pytest.raises(ValueError, match="multiple of"):
            parallel.check_batch_size(mesh.size + 1, mesh)
    batch = parallel.shard_batch({"patches": np.zeros((4, 3, 3), np.float32)}, mesh)
    assert batch["patches"].shape == (4, 3, 3)
    with pytest.raises(ValueError, match="go together"):
        parallel.initialize(coordinator="localhost:1234")
