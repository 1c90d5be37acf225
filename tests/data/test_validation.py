"""Validation pairs fused from posed RGB-D frames: real Kinect frames (3DMatch toolbox) when
present, else the embedded synthetic table-top frames (same layout)."""
import json

import numpy as np
import pytest

from sphere_jax import checks
from sphere_jax.data import patches, poses, validation
from sphere_jax.data.readers import io, rgbd, threedmatch


def test_pairs_follow_the_ground_truth_convention(frames, tmp_path):
    """Each pair's gt.log transform brings fragment j onto fragment i (p_i = T p_j) with the
    overlap it records; its inverse (the convention turned round) does not."""
    n = max(1, len(rgbd.read_frame_sequence(frames)) // 3)
    summary = validation.write_scene(frames, tmp_path / "scene", n, n)
    transforms, count = threedmatch.read_gt_log(str(tmp_path / "scene" / "gt.log"))
    assert summary["pairs"] == len(transforms) > 0
    assert count == len(summary["fragments"])
    overlaps = threedmatch.read_gt_overlap(str(tmp_path / "scene" / "gt_overlap.log"))
    voxel = validation.OVERLAP_VOXEL
    cloud = lambda k: patches.voxel_downsample(
        io.read_points(str(tmp_path / "scene" / f"cloud_bin_{k}.ply")).points, voxel)
    for (i, j), t in transforms.items():
        right = poses.overlap(cloud(i), cloud(j), t, voxel)
        turned = poses.overlap(cloud(i), cloud(j), np.linalg.inv(t), voxel)
        print(f"pair {i}-{j}: overlap {right:.2f}, under the inverse {turned:.2f}")
        assert right == pytest.approx(overlaps[(i, j)], abs=1e-3)
        assert right > validation.MIN_OVERLAP
        assert right > turned or np.allclose(t, np.eye(4), atol=1e-2)
    assert json.loads((tmp_path / "scene" / "validation.json").read_text())["pairs"] == \
        len(transforms)


def test_a_folder_without_a_sequence_is_refused(tmp_path):
    with pytest.raises(checks.MissingError, match="no posed RGB-D sequence"):
        validation.write_scene(tmp_path, tmp_path / "out")
