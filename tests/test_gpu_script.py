"""experiments/gpu_paper.sh, the accelerator run of the 'paper' networks, at the tests' size on
this CPU: from a pack of scans to a loadable bundle stopped by its time budget (one kind: every
kind's training is tested in tests/test_training.py)."""
import json
import os
import subprocess
import tarfile

import numpy as np
import pytest

from sphere_jax import api
from sphere_jax.data import pipeline
from sphere_jax.data.generators import synthetic
from tests.data.generators.test_synthetic import SMALL

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    root = tmp_path_factory.mktemp("gpu_script_data")
    synthetic.make_all(str(root), seed=5, n_scenes=1, **SMALL)
    return str(root / "3dmatch")


def test_pack_trains_the_same_keypoints_and_batches(scans, tmp_path):
    folders = pipeline.pack_scans(scans, 0.04, str(tmp_path / "pack"))
    make = lambda paths_: pipeline.PatchSource(paths_, 0.04, 0.5, 0.5, 32, 20, seed=1)
    a, b = make(pipeline.scan_paths(scans)), make(pipeline.scan_paths(",".join(folders)))
    assert len(a) == len(b) > 0
    np.testing.assert_array_equal(a.batch(2, 4)["patches"], b.batch(2, 4)["patches"])
    folder_a, = {k.split(" ")[0] for k in a.statement()["folders"]}
    assert all(k == f"{folder_a} (packed at 0.04 m)" for k in b.statement()["folders"])


def test_gpu_script_brings_back_a_bundle_stopped_by_its_budget(scans, tmp_path):
    carry = tmp_path / "carry"
    pipeline.pack_scans(scans, 0.04, str(carry / "pack"))
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, CARRY=str(carry), SIZE="tiny", OUT=str(out), KINDS="lead_pn")
    subprocess.run(["bash", "experiments/gpu_paper.sh", "train", "0.0001",
                    "--config.data.voxel=0.04", "--config.data.radius=0.5",
                    "--config.data.keypoint_leaf=0.5", "--config.train.steps=50",
                    "--host_devices=1"], cwd=ROOT, env=env, check=True, capture_output=True)
    with tarfile.open(out / "lead_pn_tiny.tar.gz") as t:
        t.extractall(tmp_path / "back", filter="data")
    b = api.load_bundle(tmp_path / "back" / "lead_pn" / "bundle")
    assert b.config.model == "lead_pn"
    assert b.config.train.steps_done == 1 < b.config.train.steps == 50    # the budget ended it
    steps = [json.loads(x)["step"] for x in
             (tmp_path / "back" / "lead_pn" / "metrics.jsonl").read_text().splitlines()]
    assert steps == [1]
