"""Rotation-invariant classification: Compass + PointNet keeps its accuracy under rotation,
plain PointNet does not (embedded shapes, the shipped B = 8 whole-shape Compass)."""
import csv

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from configs import eval_classification
from sphere_jax import checks
from sphere_jax.data import oriented
from sphere_jax.eval import classification
from sphere_jax.models import shipped

@pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop
def test_compass_pointnet_keeps_accuracy_under_rotation(tmp_path):
    c = eval_classification.get_config("tiny")
    c.methods = "pointnet,compass+pointnet"
    c.data.n_points = 256
    c.train.update(steps=400, batch_size=16, log_every=100, eval_every=400,
                   checkpoint_every=400)
    c.model_kwargs = dict(features=(32, 32, 64), head=(32,))
    # The shipped 'small' whole-shape Compass (B = 8): half the time of the default 'mid' one
    # (36 s against 72 s here), which the shipped-outputs fixture checks.
    c.compass_bundle = shipped.bundle_path("compass_shapes_small", required=True)
    rows, md = classification.run(c, str(tmp_path), progress=False)
    print(md)
    acc = {(r["method"], r["split"]): r["accuracy"] for r in rows}
    with open(tmp_path / "classification.csv") as f:
        assert [r["split"] for r in csv.DictReader(f)] == ["NR", "AR", "NR", "AR"]
    assert acc[("pointnet", "NR")] > 0.4                          # chance: 1/12
    assert acc[("pointnet", "AR")] < acc[("pointnet", "NR")] - 0.2   # plain PointNet drops
    # The stated margin: the small shipped Compass (B = 8; validation geodesic error 1.02 rad,
    # many shapes are symmetric) keeps all but a quarter of the accuracy plain PointNet loses
    # — measured here: a drop of 0.03 against 0.70 — and beats it in AR by 0.4 or more (0.92
    # against 0.27).
    compass_drop = acc[("compass+pointnet", "NR")] - acc[("compass+pointnet", "AR")]
    assert compass_drop < 0.25 * (acc[("pointnet", "NR")] - acc[("pointnet", "AR")])
    assert acc[("compass+pointnet", "AR")] > acc[("pointnet", "AR")] + 0.4


def test_compass_train_rotated_turns_only_compass_training_shapes():
    c = eval_classification.get_config("tiny")
    c.compass_bundle = shipped.bundle_path("compass_shapes_small", required=True)
    assert not classification.method_config(c, "compass+pointnet").data.rotate
    assert classification.method_config(c, "compass_train_rotated").data.rotate
    assert classification.method_config(c, "compass_train_rotated").orient_bundle
    # plain PointNet is the rotation-sensitive reference: it always trains in canonical pose
    plain = classification.method_config(c, "pointnet")
    assert not plain.data.rotate and not plain.orient_bundle
    with pytest.raises(ValueError, match="one of"):
        classification.method_config(c, "pointnet++")


def test_missing_compass_bundle_is_named(tmp_path):
    c = eval_classification.get_config("tiny")
    c.compass_bundle = str(tmp_path / "no_bundle")
    with pytest.raises(checks.MissingError, match="compass_bundle="):
        classification.method_config(c, "compass+pointnet")
    classification.method_config(c, "pointnet")   # plain PointNet does not need it


def test_frame_angles_are_the_angles_between_turned_frames(monkeypatch, tmp_path):
    """0° for an orienter that turns with the shape; the turn's own angle for one that does not
    (the identity frame), and the per-class table counts the shapes within 15°."""
    monkeypatch.setenv("SPHERE_JAX_DATA", str(tmp_path))
    rng = np.random.default_rng(0)
    shapes = [rng.normal(size=(32, 3)) * [3, 2, 1] for _ in range(4)]
    turns = np.stack([Rotation.from_rotvec([0, 0, np.radians(a)]).as_matrix()
                      for a in (5, 10, 40, 90)])
    turned = oriented.turn(shapes, turns)

    class Fixed:
        key = "identity"

        def frames(self, x):
            return x.mean(1, keepdims=True), np.repeat(np.eye(3)[None], len(x), 0)

    class Equivariant(Fixed):
        key = "equivariant"

        def frames(self, x):                   # a turned shape's frame: the turn that made it
            c, f = Fixed.frames(self, x)
            for k, p in enumerate(x):
                f[k] = next((t for s, t in zip(turned, turns) if np.array_equal(s, p)), f[k])
            return c, f

    what = {"root": "r", "split": "test", "rule": ""}

    def angles(orienter):
        _, f0 = oriented.frames(orienter, shapes, {**what, "turns": None}, progress=False)
        _, fr = oriented.frames(orienter, turned, {**what, "turns": 0}, progress=False)
        return classification.frame_angles(turns, f0, fr)

    np.testing.assert_allclose(angles(Equivariant()), 0, atol=0.05)
    angle = angles(Fixed())
    np.testing.assert_allclose(angle, [5, 10, 40, 90], atol=0.05)   # float32 frames
    rows = classification.frame_table(angle, np.array([0, 0, 1, 1]), ["a", "b"],
                                      np.array([True, False, True, True]), "m")
    by = {r["class"]: r for r in rows}
    assert by["all"]["frame_within"] == 0.5 and by["a"]["frame_within"] == 1.0
    assert by["b"]["frame_within"] == 0.0 and by["a"]["ar_accuracy_within"] == 0.5
    assert np.isnan(by["a"]["ar_accuracy_beyond"]) and by["b"]["ar_accuracy_beyond"] == 1.0
