"""The batch of a step: a classifier's shapes go through the orientation the caller passes."""
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


def test_orient_shapes_turns_every_batch_of_an_oriented_classifier(config):
    source = training.build_source(config)
    plain = training.get_batch(config, source, 3)
    flip = np.diag([1.0, -1.0, -1.0]).astype(np.float32)        # a proper rotation
    config.orient_bundle = "a whole-shape Compass"
    seen = []

    def orient(shapes_BxNx3):
        seen.append(shapes_BxNx3.shape)
        return shapes_BxNx3 @ flip

    try:
        turned = training.get_batch(config, source, 3, orient_shapes=orient)
        np.testing.assert_array_equal(turned["points"], plain["points"] @ flip)
        np.testing.assert_array_equal(turned["labels"], plain["labels"])
        assert seen == [plain["points"].shape]
    finally:
        config.orient_bundle = ""


def test_an_oriented_classifier_without_orient_shapes_is_refused_before_work(config, tmp_path):
    c = classify.get_config("tiny")
    c.data.root = config.data.root
    c.orient_bundle = "runs/compass_shapes_small/bundle"
    workdir = tmp_path / "run"
    with pytest.raises(checks.ConfigError, match="config.orient_bundle.*orient_shapes"):
        training.train_and_evaluate(c, str(workdir), progress=False)
    assert not os.path.exists(workdir)
