import os

import numpy as np
import pytest
from sklearn.neighbors import NearestNeighbors

from sphere_jax.data.readers import io
from sphere_jax.data.readers import rgbd, stanford, threedmatch


def _transform(points, t):
    return points @ t[:3, :3].T + t[:3, 3]


def test_3dmatch_scene_ground_truth_aligns(shared):
    scene = threedmatch.load_fragment_scene(os.path.join(shared, "3dmatch/7-scenes-redkitchen"))
    assert scene.fragments == [0, 5, 6, 21, 34]
    assert scene.pairs == [(0, 5), (0, 6), (5, 6), (5, 21), (6, 21)]
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
    assert (0, 34) in lo.pairs and all(lo.overlaps[p] < 0.35 for p in lo.pairs if 34 in p)


def test_stanford_bunny_conf_aligns_scans(shared):
    root = os.path.join(shared, "stanford/bunny/data")
    conf = stanford.read_stanford_conf(os.path.join(root, "bun.conf"))
    p0 = io.read_ply(os.path.join(root, "bun000.ply")).points
    p45 = io.read_ply(os.path.join(root, "bun045.ply")).points
    nn = NearestNeighbors(n_neighbors=1).fit(_transform(p0, conf["bun000.ply"]))
    d = nn.kneighbors(_transform(p45, conf["bun045.ply"]))[0][:, 0]
    overlap = d < 0.002
    assert overlap.mean() > 0.5 and d[overlap].mean() < 0.001
    d_raw = NearestNeighbors(n_neighbors=1).fit(p0).kneighbors(p45)[0][:, 0]
    assert np.mean(d_raw < 0.002) < overlap.mean() - 0.2
    scans = stanford.load_stanford_scans(os.path.join(root, "bun.conf"))
    t = scans.transform("bun000.ply", "bun045.ply")                   # 45 -> 0
    d_pair = nn.kneighbors(_transform(_transform(p45, t), conf["bun000.ply"]))[0][:, 0]
    np.testing.assert_allclose(d_pair, d, atol=1e-5)


def test_rgbd_frames_fuse_under_their_poses(shared):
    root = os.path.join(shared, "rgbd/3dmatch_toolbox")
    k = rgbd.read_intrinsics(os.path.join(root, "camera-intrinsics.txt"))
    frame = lambda n: os.path.join(root, "rgbd-frames", f"frame-{n:06d}")
    clouds = [rgbd.read_rgbd_frame(frame(n) + ".color.png", frame(n) + ".depth.png", k,
                                       rgbd.read_pose(frame(n) + ".pose.txt"))
              for n in (8, 20)]
    d = NearestNeighbors(n_neighbors=1).fit(clouds[0].points).kneighbors(
        clouds[1].points[::7])[0]
    assert np.mean(d < 0.02) > 0.90
    assert clouds[0].colors.shape == clouds[0].points.shape and clouds[0].colors.max() <= 1


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


def test_shape_source_reads_the_three_modelnet_layouts(shared, tmp_path):
    import numpy as np
    import pytest
    from sphere_jax.data import pipeline
    off = pipeline.ShapeSource(os.path.join(shared, "modelnet40", "off_meshes", "ModelNet10"),
                               256)
    assert off.classes == ["sofa", "table"]
    pts = off.splits["train"][0][0]
    assert pts.shape == (10_000, 3) and abs(np.linalg.norm(pts, axis=1).max() - 1) < 1e-5
    res = pipeline.ShapeSource(os.path.join(shared, "modelnet40",
                                            "modelnet40_normal_resampled"), 256)
    assert len(res.classes) == 40 and len(res.splits["train"][0]) == 127
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="no ModelNet layout"):
        pipeline.ShapeSource(empty, 32)


def test_shape_source_reads_pointnet_h5(tmp_path):
    import numpy as np
    import pytest
    from sphere_jax.data import pipeline
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "ply_data_train0.h5", "w") as f:
        f["data"] = np.random.default_rng(0).normal(size=(3, 64, 3)).astype(np.float32)
        f["label"] = np.array([[0], [2], [1]])
    h5 = pipeline.ShapeSource(tmp_path, 32)
    assert h5.classes == ["0", "1", "2"] and h5.batch(0, 2)["points"].shape == (2, 32, 3)
