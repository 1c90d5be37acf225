"""3DMatch layout: real ground truth aligns fragments; gt.log round trip and errors."""
import os

import numpy as np
import pytest
from sklearn.neighbors import NearestNeighbors

from sphere_jax.data.readers import io, stanford, threedmatch


def _transform(points, t):
    return points @ t[:3, :3].T + t[:3, 3]


def test_3dmatch_scene_ground_truth_aligns(shared):
    scene = threedmatch.load_fragment_scene(os.path.join(shared, "3dmatch/7-scenes-redkitchen"))
    assert scene.fragments == [0, 4, 5, 6, 7, 21, 34, 59]
    assert scene.pairs == [(0, 4), (0, 5), (0, 6), (4, 5), (4, 6), (4, 7), (5, 6), (5, 7),
                           (5, 21), (6, 7), (6, 21), (6, 59), (7, 21), (7, 59)]
    a, b = scene.cloud(0).points, scene.cloud(5).points
    nn = NearestNeighbors(n_neighbors=1).fit(a)
    aligned = np.mean(nn.kneighbors(_transform(b, scene.transforms[(0, 5)]))[0] < 0.05)
    raw = np.mean(nn.kneighbors(b)[0] < 0.05)
    assert aligned > 0.40 and raw < 0.15
    # The fragment poses agree with gt.log: T_ij = A_i⁻¹ A_j.
    a0 = threedmatch.read_fragment_info(scene.fragment_path(0).replace(".ply", ".info.txt"))[-1]
    a5 = threedmatch.read_fragment_info(scene.fragment_path(5).replace(".ply", ".info.txt"))[-1]
    np.testing.assert_allclose(np.linalg.inv(a0) @ a5, scene.transforms[(0, 5)], atol=1e-6)
    assert 0 < scene.overlaps[(0, 5)] < 1 and scene.info[(0, 5)].shape == (6, 6)
    lo = threedmatch.load_fragment_scene(
        os.path.join(shared, "3dmatch/7-scenes-redkitchen"),
        os.path.join(shared, "3dmatch/3DLoMatch/7-scenes-redkitchen-evaluation"))
    assert len(lo.pairs) == 13
    assert (0, 34) in lo.pairs and all(lo.overlaps[p] < 0.35 for p in lo.pairs if 34 in p)


def test_gt_log_round_trip_and_errors(tmp_path):
    t = {(0, 1): np.eye(4), (2, 5): np.diag([1.0, -1.0, -1.0, 1.0])}
    threedmatch.write_gt_log(tmp_path / "gt.log", t, 6)
    back, n = threedmatch.read_gt_log(tmp_path / "gt.log")
    assert n == 6 and set(back) == set(t)
    np.testing.assert_array_equal(back[(2, 5)], t[(2, 5)])
    lines = (tmp_path / "gt.log").read_text().splitlines()
    (tmp_path / "cut.log").write_text("\n".join(lines[:-2]) + "\n")
    with pytest.raises(io.DataError, match="truncated"):
        threedmatch.read_gt_log(tmp_path / "cut.log")
    (tmp_path / "bad.conf").write_text("bmesh a.ply 0 0 0 0 0 1\n")
    with pytest.raises(io.DataError, match="line 1"):
        stanford.read_stanford_conf(tmp_path / "bad.conf")
    with pytest.raises(io.DataError, match="no cloud_bin_K.ply"):
        threedmatch.load_fragment_scene(tmp_path)


@pytest.mark.parametrize("edit, message", [
    (lambda ls: ["0.5 1 2"] + ls[1:],
     "line 1: block header 'i j n' must hold non-negative integers"),
    (lambda ls: ls[:5] + ls[:5], r"line 6: pair \(0, 1\) given twice \(first at line 1\)"),
    (lambda ls: ls[:1] + [ls[1].replace("1", "2", 1)] + ls[2:5],
     r"line 2: pair \(0, 1\): the matrix is not a rigid transform"),
])
def test_gt_log_ids_pairs_and_matrices_checked(tmp_path, edit, message):
    threedmatch.write_gt_log(tmp_path / "gt.log", {(0, 1): np.eye(4)}, 2)
    lines = (tmp_path / "gt.log").read_text().splitlines()
    (tmp_path / "bad.log").write_text("\n".join(edit(lines)) + "\n")
    with pytest.raises(io.DataError, match=message):
        threedmatch.read_gt_log(tmp_path / "bad.log")


def test_conf_with_a_zero_quaternion_is_refused(tmp_path):
    (tmp_path / "z.conf").write_text("camera 0 0 0 0 0 0 1\nbmesh a.ply 0 0 0 0 0 0 0\n")
    with pytest.raises(io.DataError, match="line 2: the quaternion of a.ply is zero"):
        stanford.read_stanford_conf(tmp_path / "z.conf")


def test_empty_or_foreign_ground_truth_is_refused(tmp_path):
    from sphere_jax.data.readers import ply
    ply.write_ply(tmp_path / "cloud_bin_0.ply", np.zeros((4, 3), np.float32))
    ply.write_ply(tmp_path / "cloud_bin_1.ply", np.zeros((4, 3), np.float32))
    (tmp_path / "gt.log").write_text("")
    with pytest.raises(io.DataError, match="gt.log: holds no pair"):
        threedmatch.read_gt_log(tmp_path / "gt.log")
    with pytest.raises(io.DataError, match="holds no pair"):
        threedmatch.load_fragment_scene(tmp_path)
    threedmatch.write_gt_log(tmp_path / "gt.log", {(5, 7): np.eye(4)}, 8)
    with pytest.raises(io.DataError, match=r"none of its 1 pairs has both clouds .*\[0, 1\]"):
        threedmatch.load_fragment_scene(tmp_path)
