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
    assert len(res.classes) == 40 and len(res.splits["train"][0]) == 127
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


def test_train_only_shape_set_gets_a_held_out_split(shared):
    root = os.path.join(shared, "modelnet40", "modelnet40_normal_resampled")
    res = pipeline.ShapeSource(root, 256, holdout_every=3)
    train, test = res.splits["train"], res.splits["test"]
    assert len(train[0]) + len(test[0]) == 127 and 20 <= len(test[0]) <= 45
    assert set(test[1]) <= set(train[1])           # every test class is also trained on
    ids = lambda split: {tuple(s[0]) for s in split[0]}
    assert not ids(train) & ids(test)
    assert res.statement()["shapes"]["test"] == len(test[0])
    with pytest.raises(ValueError, match="holdout_every"):
        pipeline.holdout_split(train[0], train[1], 1)


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
        shared = np.mean([np.isclose(back[k][:, None], b["patches"][k][None], atol=1e-5).all(-1).any(1)
                          for k in range(8)])
        return back, shared

    back, shared = unrotated("patch")
    assert shared > 0.99 and np.abs(back[..., 2]).max() < 1e-5
    back, shared = unrotated("support")
    assert shared < 0.6 and np.abs(back[..., 2]).max() < 1e-5
    back, _ = unrotated("support", jitter=0.01)
    assert 0.007 < back[..., 2].std() < 0.013
    with pytest.raises(ValueError, match="copy_draw"):
        src.batch(0, 2, copies=True, copy_draw="scan")
    with pytest.raises(ValueError, match="copy_jitter"):
        src.batch(0, 2, copies=True, copy_jitter=-1.0)
