"""The evaluation-scene rule: every known source of an evaluation scene is recognised (by its
place under the real scans, by label and by name), clean sources are not, and training
refuses them unless the run says it is an evaluation-scene experiment."""
import os

import pytest

from sphere_jax import paths, training
from sphere_jax.data import held_out as es

CLEAN = ["shared/open3d_testdata/RGBD",
         "shared/modelnet40/modelnet40_normal_resampled",
         "embedded/rooms-v2-seed1/3dmatch/synth-room-s1-0", "/data/my_scans/office.ply"]


@pytest.mark.parametrize("scene", es.EVALUATION_SCENES, ids=lambda s: s.name)
def test_every_source_of_a_scene_is_recognised(scene):
    for source in scene.sources:
        assert es.scene_of(source) is scene
        assert es.scene_of(source + "/sub/cloud_bin_0.ply") is scene \
            or source.endswith((".ply", ".pcd"))


def test_names_and_real_paths_are_recognised_and_clean_ones_are_not():
    assert es.scene_of("/mnt/3dmatch/7-scenes-redkitchen/cloud_bin_3.ply").name == "redkitchen"
    assert es.scene_of("/data/stanford/bunny/data/bun045.ply").name == "bunny"
    assert es.scene_of("/data/3dmatch/sun3d-home_at-home_at_scan1_2013_jan_1").name == \
        "sun3d-home_at"
    assert es.scene_of("shared/rgbd/3dmatch_toolbox/rgbd-frames (fused RGB-D)").name == \
        "redkitchen"
    from sphere_jax.data import scan_roots             # the main job's rooms, not the others
    assert es.scene_of(scan_roots.entry_path("embedded")).name == "embedded rooms"
    assert es.scene_of(scan_roots.entry_path("embedded:1")) is None
    root = paths.real_data_root()
    if root:
        assert es.scene_of(os.path.join(root, "open3d_testdata", "fragment.pcd")).name == \
            "sun3d-home_at"
        assert es.scene_of(os.path.join(root, "open3d_testdata", "Feature",
                                        "cloud_bin_0.pcd")).name == "open3d Feature fragments"
    assert [p for p in CLEAN if es.scene_of(p) is not None] == []


def test_check_names_each_scene_once_and_allows_a_declared_experiment():
    labels = ["shared/3dmatch/demo_fullres/cloud_bin_0.ply",
              "shared/3dmatch/7-scenes-redkitchen/cloud_bin_5.ply", "shared/stanford/bunny/data"]
    with pytest.raises(es.EvaluationSceneError,
                       match=r"evaluation scenes: bunny \(.*\); redkitchen \(.*demo_fullres"):
        es.check_training_scans(labels + CLEAN)
    assert es.check_training_scans(labels, allow=True) == ["bunny", "redkitchen"]
    assert es.check_training_scans(CLEAN) == []


def test_training_refuses_an_evaluation_scene_before_any_work(tmp_path):
    from configs import lead
    c = lead.get_config("tiny")
    c.data.root = "embedded,/elsewhere/7-scenes-redkitchen"        # need not exist
    with pytest.raises(es.EvaluationSceneError, match="redkitchen"):
        training.train_and_evaluate(c, str(tmp_path), progress=False)
    assert not os.path.exists(tmp_path / "checkpoints")
