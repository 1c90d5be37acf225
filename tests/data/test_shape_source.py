"""The shape source reads ModelNet40's released layouts and splits them three ways, the same
for every shape task."""
import os

import numpy as np
import pytest

from sphere_jax.data import shape_source


def test_shape_source_reads_the_three_modelnet_layouts(shared, tmp_path):
    off = shape_source.ShapeSource(os.path.join(shared, "modelnet40", "off_meshes", "ModelNet10"),
                               256)
    assert off.classes == ["sofa", "table"]
    pts = off.splits["train"][0][0]
    assert pts.shape == (10_000, 3) and abs(np.linalg.norm(pts, axis=1).max() - 1) < 1e-5
    res = shape_source.ShapeSource(os.path.join(shared, "modelnet40",
                                            "modelnet40_normal_resampled"), 256)
    assert len(res.classes) == 40
    assert sum(len(v[0]) for v in res.splits.values()) == 127
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="no ModelNet layout"):
        shape_source.ShapeSource(empty, 32)


def test_shape_source_reads_pointnet_h5(tmp_path):
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "ply_data_train0.h5", "w") as f:
        f["data"] = np.random.default_rng(0).normal(size=(3, 64, 3)).astype(np.float32)
        f["label"] = np.array([[0], [2], [1]])
    h5 = shape_source.ShapeSource(tmp_path, 32)
    assert h5.classes == ["0", "1", "2"] and h5.batch(0, 2)["points"].shape == (2, 32, 3)


def test_train_only_shape_set_gets_three_disjoint_splits(tmp_path):
    """A set without a test split (ModelNet40's train-only HDF5): each 5th shape of a class in
    file order tests, each 5th of the rest validates, the rest trains; no shape in two."""
    h5py = pytest.importorskip("h5py")
    labels = np.repeat([0, 1, 2], [26, 10, 4])              # class 2: too few to hold out
    data = np.random.default_rng(0).normal(size=(len(labels), 16, 3)).astype(np.float32)
    with h5py.File(tmp_path / "ply_data_train0.h5", "w") as f:
        f["data"], f["label"] = data, labels[:, None]
    src = shape_source.ShapeSource(tmp_path, 16)
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
        shape_source.ShapeSource(tmp_path, 16, val_every=1)


def test_a_set_with_its_own_test_split_keeps_it_and_validates_on_train_shapes(tmp_path):
    rng = np.random.default_rng(0)
    (tmp_path / "shape_names.txt").write_text("cup\n")
    (tmp_path / "cup").mkdir()
    for i in range(8):
        np.savetxt(tmp_path / "cup" / f"cup_{i:04d}.txt", rng.normal(size=(20, 6)),
                   delimiter=",")
    (tmp_path / "train.txt").write_text("".join(f"cup_{i:04d}\n" for i in range(6)))
    (tmp_path / "test.txt").write_text("cup_0006\ncup_0007\n")
    res = shape_source.ShapeSource(tmp_path, 16)
    assert "the set's own test split" in res.statement()["splits"]
    assert {k: len(v[0]) for k, v in res.splits.items()} == {"train": 5, "val": 1, "test": 2}
