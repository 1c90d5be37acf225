"""Training sources: the shape source reads ModelNet40's released layouts."""
import os

import numpy as np
import pytest

from sphere_jax.data import pipeline


def test_shape_source_reads_the_three_modelnet_layouts(shared, tmp_path):
    off = pipeline.ShapeSource(os.path.join(shared, "modelnet40", "off_meshes", "ModelNet10"),
                               256)
    assert off.classes == ["sofa", "table"]
    pts = off.splits["train"][0][0]
    assert pts.shape == (10_000, 3) and abs(np.linalg.norm(pts, axis=1).max() - 1) < 1e-5
    res = pipeline.ShapeSource(os.path.join(shared, "modelnet40",
                                            "modelnet40_normal_resampled"), 256)
    assert len(res.classes) == 40
    assert sum(len(v[0]) for v in res.splits.values()) == 127
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="no ModelNet layout"):
        pipeline.ShapeSource(empty, 32)


def test_shape_source_reads_pointnet_h5(tmp_path):
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "ply_data_train0.h5", "w") as f:
        f["data"] = np.random.default_rng(0).normal(size=(3, 64, 3)).astype(np.float32)
        f["label"] = np.array([[0], [2], [1]])
    h5 = pipeline.ShapeSource(tmp_path, 32)
    assert h5.classes == ["0", "1", "2"] and h5.batch(0, 2)["points"].shape == (2, 32, 3)


def test_train_only_shape_set_gets_three_disjoint_splits(tmp_path):
    """A set without a test split (ModelNet40's train-only HDF5): each 5th shape of a class in
    file order tests, each 5th of the rest validates, the rest trains; no shape in two."""
    h5py = pytest.importorskip("h5py")
    labels = np.repeat([0, 1, 2], [26, 10, 4])              # class 2: too few to hold out
    data = np.random.default_rng(0).normal(size=(len(labels), 16, 3)).astype(np.float32)
    with h5py.File(tmp_path / "ply_data_train0.h5", "w") as f:
        f["data"], f["label"] = data, labels[:, None]
    src = pipeline.ShapeSource(tmp_path, 16)
    sizes = {k: np.bincount(v[1], minlength=3).tolist() for k, v in src.splits.items()}
    # class 0: 26 shapes -> 5 test (ranks 5, 10, ..., 25), 21 left -> 4 val, 17 train
    assert sizes == {"test": [5, 2, 0], "val": [4, 1, 0], "train": [17, 7, 4]}
    ids = {k: {s.tobytes() for s in v[0]} for k, v in src.splits.items()}
    assert not (ids["train"] & ids["val"] or ids["train"] & ids["test"] or
                ids["val"] & ids["test"])
    first = lambda split: src.splits[split][0][0]
    np.testing.assert_array_equal(first("test"), data[4])    # the 5th shape of class 0
    np.testing.assert_array_equal(first("val"), data[5])     # the 5th of the rest
    assert src.statement()["shapes"] == {"train": 28, "test": 7, "val": 5}
    with pytest.raises(ValueError, match="val_every"):
        pipeline.ShapeSource(tmp_path, 16, val_every=1)


def test_a_set_with_its_own_test_split_keeps_it_and_validates_on_train_shapes(tmp_path):
    rng = np.random.default_rng(0)
    (tmp_path / "shape_names.txt").write_text("cup\n")
    (tmp_path / "cup").mkdir()
    for i in range(8):
        np.savetxt(tmp_path / "cup" / f"cup_{i:04d}.txt", rng.normal(size=(20, 6)),
                   delimiter=",")
    (tmp_path / "train.txt").write_text("".join(f"cup_{i:04d}\n" for i in range(6)))
    (tmp_path / "test.txt").write_text("cup_0006\ncup_0007\n")
    res = pipeline.ShapeSource(tmp_path, 16)
    assert "the set's own test split" in res.statement()["splits"]
    assert {k: len(v[0]) for k, v in res.splits.items()} == {"train": 5, "val": 1, "test": 2}


def test_copies_drawn_from_the_whole_support_are_a_second_sampling(tmp_path):
    """'patch' copies (the seed's) reuse the patch's own points; 'support' copies are a second
    draw from the keypoint's support: after undoing the rotation, most of their points are not
    among the patch's, yet all lie on the same surface (the plane z = 0 here), moved only by the
    requested jitter."""
    from sphere_jax.data.readers import io
    rng = np.random.default_rng(0)
    pts = np.c_[rng.uniform(0, 1.5, (6000, 2)), np.zeros(6000)].astype(np.float32)
    io.write_ply(str(tmp_path / "plane.ply"), pts)
    src = pipeline.PatchSource([str(tmp_path / "plane.ply")], voxel=0.01, keypoint_leaf=0.2,
                               radius=0.3, n_points=64, min_points=50)

    def unrotated(draw, jitter=0.0):
        b = src.batch(3, 8, copies=True, occlusion=False, copy_draw=draw, copy_jitter=jitter)
        back = np.einsum("bji,bnj->bni", b["rotations"], b["copies"])   # Rᵀ per copy
        close = lambda k: np.isclose(back[k][:, None], b["patches"][k][None], atol=1e-5)
        shared = np.mean([close(k).all(-1).any(1) for k in range(8)])
        return back, shared

    back, shared = unrotated("patch")
    assert shared > 0.99 and np.abs(back[..., 2]).max() < 1e-5
    back, shared = unrotated("support")
    assert shared < 0.6 and np.abs(back[..., 2]).max() < 1e-5
    back, _ = unrotated("support", jitter=0.01)
    assert 0.007 < back[..., 2].std() < 0.013
    with pytest.raises(ValueError, match="copy_draw"):
        src.batch(0, 2, copies=True, copy_draw="mesh")
    with pytest.raises(ValueError, match="copy_jitter"):
        src.batch(0, 2, copies=True, copy_jitter=-1.0)


def test_scene_poses_chain_the_ground_truth(tmp_path):
    """Poses from a gt.log whose pairs form a chain 0-1, 1-2 (no 0-2 pair): fragment 2 is
    reached through 1, so p_0 = P_2 p_2 with P_2 = T_01 T_12; a scan outside any scene gets -1."""
    from sphere_jax.data import poses
    from sphere_jax.data.readers import io, threedmatch
    from sphere_jax.spherical import so3
    scene = tmp_path / "room"
    scene.mkdir()
    for k in range(3):
        io.write_ply(str(scene / f"cloud_bin_{k}.ply"), np.zeros((4, 3), np.float32))
    io.write_ply(str(tmp_path / "loose.ply"), np.zeros((4, 3), np.float32))
    t01, t12 = np.eye(4), np.eye(4)
    t01[:3, :3], t01[:3, 3] = so3.euler_to_matrix_np(0.3, 0.5, 0.7), [1, 0, 0]
    t12[:3, :3], t12[:3, 3] = so3.euler_to_matrix_np(-0.2, 1.1, 0.4), [0, 2, 0]
    threedmatch.write_gt_log(str(scene / "gt.log"), {(0, 1): t01, (1, 2): t12}, 3)
    paths_ = [str(scene / f"cloud_bin_{k}.ply") for k in (2, 0, 1)] + [str(tmp_path / "loose.ply")]
    ids, pose = poses.scene_poses(paths_)
    assert ids.tolist() == [0, 0, 0, -1] and np.isnan(pose[3]).all()
    np.testing.assert_allclose(pose[1], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(pose[2], t01, atol=1e-12)
    np.testing.assert_allclose(pose[0], t01 @ t12, atol=1e-12)


def test_scan_copies_are_the_same_surface_seen_by_another_scan():
    """copy_draw='scan' on the embedded rooms (ground-truth poses): almost no copy shares a
    point with its patch (it comes from another fragment), yet turned back by the batch's
    rotation it lies on the patch's surface as closely as a second draw from the same scan
    does (mean distance to the patch's nearest point, in units of the radius)."""
    from sklearn.neighbors import KDTree
    src = pipeline.PatchSource(pipeline.scan_paths("embedded"), 0.02, 0.1, 0.3, 256, 300)

    def gap_and_shared(draw):
        b = src.batch(0, 16, copies=True, occlusion=False, copy_draw=draw)
        back = np.einsum("bji,bnj->bni", b["rotations"], b["copies"])
        gap = np.median([KDTree(p).query(q, k=1)[0].mean() for p, q in zip(b["patches"], back)])
        shared = np.mean([np.isclose(q[:, None], p[None], atol=1e-5).all(-1).any(1).mean()
                          for p, q in zip(b["patches"], back)])
        return gap, shared

    support_gap, support_shared = gap_and_shared("support")
    scan_gap, scan_shared = gap_and_shared("scan")
    print(f"support: gap {support_gap:.3f}, shared {support_shared:.2f}; "
          f"scan: gap {scan_gap:.3f}, shared {scan_shared:.2f}")
    assert support_shared > 0.2 and scan_shared < 0.05
    assert scan_gap < 1.5 * support_gap and scan_gap < 0.1
