"""Data-parallel training over a mesh of host devices (two CPU devices, forced through
XLA_FLAGS in child processes: the device count is fixed when JAX starts)."""
import os
import subprocess
import sys

import jax
import numpy as np
import pytest

from sphere_jax import parallel
from tests.test_training import tiny

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
    """In the child: ROOT WORKDIR DEVICES STEPS -> WORKDIR/params.npy."""
    import pathlib
    from sphere_jax import training
    root, workdir, devices, steps = sys.argv[1:5]
    c = tiny("compass", pathlib.Path(root), steps=int(steps), checkpoint_every=2,
             eval_every=100, log_every=1)
    c.train.devices = int(devices)
    state, _ = training.train_and_evaluate(c, workdir, progress=False)
    np.save(os.path.join(workdir, "params.npy"), _frame_parameters(state["params"]))


def _train(root, workdir, devices, steps):
    """Train the tiny Compass config in a child process that has two host devices."""
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    code = "from tests.test_parallel import child_main; child_main()"
    out = subprocess.run([sys.executable, "-c", code, str(root), str(workdir), str(devices),
                          str(steps)], cwd=REPO, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    return np.load(os.path.join(workdir, "params.npy"))


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_device_counts_agree_and_runs_repeat_bitwise(small_root_parallel, tmp_path):
    one = _train(small_root_parallel, tmp_path / "one", 1, 10)
    two = _train(small_root_parallel, tmp_path / "two", 2, 10)
    again = _train(small_root_parallel, tmp_path / "again", 2, 10)
    np.testing.assert_array_equal(two, again)
    assert _rel(two, one) <= 1e-6
    # Interrupted after 4 steps on two devices, resumed on one.
    _train(small_root_parallel, tmp_path / "resumed", 2, 4)
    resumed = _train(small_root_parallel, tmp_path / "resumed", 1, 10)
    assert _rel(resumed, one) <= 1e-6
    assert _rel(one, _train(small_root_parallel, tmp_path / "short", 1, 4)) > 1e-3


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
