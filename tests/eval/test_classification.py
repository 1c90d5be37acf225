"""Rotation-invariant classification: Compass + PointNet keeps its accuracy under rotation,
plain PointNet does not (embedded shapes, the shipped B = 8 whole-shape Compass)."""
import csv

import pytest

from configs import eval_classification
from sphere_jax import checks, paths
from sphere_jax.eval import classification

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop


def test_compass_pointnet_keeps_accuracy_under_rotation(tmp_path):
    c = eval_classification.get_config("tiny")
    c.data.n_points = 256
    c.train.update(steps=400, batch_size=16, log_every=100, eval_every=400,
                   checkpoint_every=400)
    c.model_kwargs = dict(features=(32, 32, 64), head=(32,))
    # The shipped 'small' whole-shape Compass (B = 8): half the time of the default 'mid' one
    # (36 s against 72 s here), which the shipped-outputs fixture checks.
    c.compass_bundle = paths.shipped_bundle("compass_shapes_small", required=True)
    rows, md = classification.run(c, str(tmp_path), progress=False)
    print(md)
    acc = {(r["method"], r["split"]): r["accuracy"] for r in rows}
    with open(tmp_path / "classification.csv") as f:
        assert [r["split"] for r in csv.DictReader(f)] == ["NR", "AR", "NR", "AR"]
    assert acc[("pointnet", "NR")] > 0.4                          # chance: 1/12
    assert acc[("pointnet", "AR")] < acc[("pointnet", "NR")] - 0.2   # plain PointNet drops
    # The stated margin: the small shipped Compass (validation geodesic error 1.04 rad, many
    # shapes are symmetric) keeps at least 40 % of the accuracy plain PointNet loses — measured
    # here: a drop of 0.35 against 0.75 — and beats it in AR by 0.2 or more (0.52 vs 0.23).
    compass_drop = acc[("compass+pointnet", "NR")] - acc[("compass+pointnet", "AR")]
    assert compass_drop < 0.6 * (acc[("pointnet", "NR")] - acc[("pointnet", "AR")])
    assert acc[("compass+pointnet", "AR")] > acc[("pointnet", "AR")] + 0.2


def test_compass_train_rotated_turns_only_compass_training_shapes():
    c = eval_classification.get_config("tiny")
    c.compass_bundle = paths.shipped_bundle("compass_shapes_small", required=True)
    assert not classification.method_config(c, "compass+pointnet").data.rotate
    c.compass_train_rotated = True
    assert classification.method_config(c, "compass+pointnet").data.rotate
    # plain PointNet is the rotation-sensitive reference: it always trains in canonical pose
    assert not classification.method_config(c, "pointnet").data.rotate


def test_missing_compass_bundle_is_named(tmp_path):
    c = eval_classification.get_config("tiny")
    c.compass_bundle = str(tmp_path / "no_bundle")
    with pytest.raises(checks.MissingError, match="compass_bundle="):
        classification.method_config(c, "compass+pointnet")
    classification.method_config(c, "pointnet")   # plain PointNet does not need it
