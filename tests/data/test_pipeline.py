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
