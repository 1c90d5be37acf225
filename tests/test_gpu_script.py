"""experiments/gpu_train.sh, the training run on a lent accelerator, at the tests' size on
this CPU: from a pack of scans to a loadable bundle stopped by its time budget (one kind: every
kind's training is tested in tests/test_training.py)."""
import json
import os
import subprocess
import tarfile

import numpy as np
import pytest

from sphere_jax import checks
from sphere_jax.bundles import inference
from configs import lead_pn
from sphere_jax.data import held_out, patch_source, scan_roots
from sphere_jax.training import inputs
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
    folders = scan_roots.pack_scans(scans, 0.04, str(tmp_path / "pack"))
    make = lambda paths_: patch_source.PatchSource(paths_, 0.04, 0.5, 0.5, 32, 20, seed=1)
    a, b = make(scan_roots.scan_paths(scans)), make(scan_roots.scan_paths(",".join(folders)))
    assert len(a) == len(b) > 0
    np.testing.assert_array_equal(a.batch(2, 4)["patches"], b.batch(2, 4)["patches"])
    folder_a, = {k.split(" ")[0] for k in a.statement()["folders"]}
    assert all(k == f"{folder_a} (packed at 0.04 m)" for k in b.statement()["folders"])


def test_a_pack_stands_in_for_its_entries(scans, tmp_path):
    folders = list(scan_roots.pack_scans(scans, 0.04, str(tmp_path / "pack")))
    assert scan_roots.packed_folders(scans, str(tmp_path / "pack")) == folders
    assert scan_roots.scan_groups(scans, pack=str(tmp_path / "pack")) == \
        [scan_roots.find_scans(f) for f in folders]
    with pytest.raises(checks.ConfigError, match="embedded:7"):
        scan_roots.packed_folders(f"{scans},embedded:7", str(tmp_path / "pack"))
    with pytest.raises(checks.ConfigError, match="must be a folder made by"):
        scan_roots.packed_folders(scans, str(tmp_path / "nowhere"))
    assert [scan_roots.scan_folder_label(p) for f in folders for p in scan_roots.find_scans(f)] \
        == [scan_roots.scan_folder_label(p) + " (packed at 0.04 m)"
            for p in scan_roots.scan_paths(scans)]


def test_a_pack_of_an_evaluation_scene_is_refused(scans, tmp_path):
    """The rule holds where only the pack is: its scans name their origin (here the bunny's,
    under an innocent data.root)."""
    folder, = scan_roots.pack_scans(scans, 0.04, str(tmp_path / "pack"))
    index_path = os.path.join(folder, scan_roots.PACK_INDEX)
    with open(index_path) as f:
        index = json.load(f)
    index["scans"] = {k: "shared/stanford/bunny/data" for k in index["scans"]}
    with open(index_path, "w") as f:
        json.dump(index, f)
    config = lead_pn.get_config("tiny")
    config.data.root, config.train.pack = scans, str(tmp_path / "pack")
    with pytest.raises(held_out.EvaluationSceneError, match="bunny"):
        inputs.check_roots(config)


def test_gpu_script_brings_back_a_bundle_stopped_by_its_budget(scans, tmp_path):
    carry = tmp_path / "carry"
    scan_roots.pack_scans(scans, 0.04, str(carry / "pack"))
    (carry / "root.txt").write_text(scans + "\n")
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, CARRY=str(carry), SIZE="tiny", OUT=str(out), KINDS="lead_pn")
    subprocess.run(["bash", "experiments/gpu_train.sh", "train", "0.0001",
                    "--config.data.voxel=0.04", "--config.data.radius=0.5",
                    "--config.data.keypoint_leaf=0.5", "--config.train.steps=50",
                    "--host_devices=1"], cwd=ROOT, env=env, check=True, capture_output=True)
    with tarfile.open(out / "lead_pn_tiny.tar.gz") as t:
        t.extractall(tmp_path / "back", filter="data")
    b = inference.load_bundle(tmp_path / "back" / "lead_pn" / "bundle")
    assert b.config.model == "lead_pn"
    assert b.config.data.root == scans and b.config.train.pack == str(carry / "pack")
    assert b.config.train.steps_done == 1 < b.config.train.steps == 50    # the budget ended it
    steps = [json.loads(x)["step"] for x in
             (tmp_path / "back" / "lead_pn" / "metrics.jsonl").read_text().splitlines()]
    assert steps == [1]
