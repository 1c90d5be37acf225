"""The batch of a step: a classifier's shapes in the frames of the orientation the caller passes,
oriented once when the source is built."""
import os

import numpy as np
import pytest

from configs import classify
from sphere_jax import checks, training
from sphere_jax.data.generators import synthetic
from tests.data.generators.test_synthetic import SMALL


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    root = tmp_path_factory.mktemp("shapes")
    synthetic.make_all(str(root), seed=5, n_scenes=1, **SMALL)
    c = classify.get_config("tiny")
    c.data.root = str(root / "modelnet")
    return c


class Flip:
    """A constant frame (a proper rotation) that counts the shapes it orients."""
    key = "flip"
    frame = np.diag([1.0, -1.0, -1.0])

    def __init__(self):
        self.seen = 0

    def frames(self, shapes_BxNx3):
        self.seen += len(shapes_BxNx3)
        return np.zeros((len(shapes_BxNx3), 1, 3)), np.repeat(self.frame[None],
                                                               len(shapes_BxNx3), 0)


def test_an_oriented_classifier_reads_each_shape_oriented_once(config, monkeypatch, tmp_path):
    monkeypatch.setenv("SPHERE_JAX_DATA", str(tmp_path))
    plain_source = training.build_source(config)
    plain = training.get_batch(config, plain_source, 3)
    c = classify.get_config("tiny")
    c.data.root, c.orient_bundle = config.data.root, "a whole-shape Compass"
    flip = Flip()
    source = training.build_source(c, orient_shapes=flip, progress=False)
    n_shapes = sum(len(v[0]) for v in plain_source.splits.values())
    assert flip.seen == n_shapes
    for step in range(3):
        training.get_batch(c, source, step)
    assert flip.seen == n_shapes                       # batches do not orient again
    turned = training.get_batch(c, source, 3)
    np.testing.assert_allclose(turned["points"], plain["points"] @ Flip.frame, atol=1e-6)
    np.testing.assert_array_equal(turned["labels"], plain["labels"])
    assert source.statement()["orientation"] == {"orienter": "flip", "rotated_copies": 0}
    c.data.rotate = True                               # turned copies, oriented once each
    copies = training.build_source(c, orient_shapes=Flip(), progress=False)
    assert len(copies.splits["train"][0]) == 8 * len(plain_source.splits["train"][0])


def test_an_oriented_classifier_without_orient_shapes_is_refused_before_work(config, tmp_path):
    c = classify.get_config("tiny")
    c.data.root = config.data.root
    c.orient_bundle = "runs/compass_shapes_small/bundle"
    workdir = tmp_path / "run"
    with pytest.raises(checks.ConfigError, match="config.orient_bundle.*orient_shapes"):
        training.train_and_evaluate(c, str(workdir), progress=False)
    assert not os.path.exists(workdir)
