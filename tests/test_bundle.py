"""Bundle folders: what training writes is what the API loads, with the training-data
statement beside the weights."""
import jax
import numpy as np
import pytest

from configs import lead
from sphere_jax import api, bundle, models, paths
from tests import reference


def test_save_load_round_trip_and_training_data(tmp_path):
    config = lead.get_config("tiny")
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    variables = reference.init(model, x)
    statement = {"kind": "scans", "folders": {"/data/a": 3}, "keypoints": {"train": 9}}
    path = bundle.save(tmp_path / "b", config, dict(variables), statement)
    assert bundle.is_bundle(path) and bundle.read_config(path).model == "lead"
    assert bundle.read_training_data(path) == statement
    back = bundle.read_variables(path)
    flat = lambda t: jax.tree_util.tree_leaves(t)
    assert all(np.array_equal(a, b) for a, b in zip(flat(back), flat(dict(variables))))
    loaded = api.load_bundle(path)
    assert loaded.kind == "lead" and loaded.spec is models.spec("lead")
    with pytest.raises(ValueError, match="not a bundle"):
        bundle.read_config(tmp_path)


def test_shipped_bundles_state_what_they_were_trained_on():
    for name in paths.SHIPPED:
        data = bundle.read_training_data(paths.shipped_bundle(name, required=True))
        assert data["folders"], name


def test_unknown_model_kind_names_the_kinds():
    with pytest.raises(ValueError, match="unknown model 'pointnet2'; the kinds are compass"):
        models.spec("pointnet2")


def test_portable_labels_of_data_folders(tmp_path, monkeypatch):
    monkeypatch.setenv("SPHERE_JAX_DATA", str(tmp_path / "cache"))
    assert paths.portable(tmp_path / "cache" / "synthetic-v1-seed0" / "3dmatch") == \
        "embedded/synthetic-v1-seed0/3dmatch"
    assert paths.portable(tmp_path / "elsewhere") == str(tmp_path / "elsewhere")
    monkeypatch.setenv("SPHERE_JAX_REAL_DATA", str(tmp_path))
    (tmp_path / "3dmatch").mkdir()
    assert paths.portable(tmp_path / "3dmatch" / "x") == "shared/3dmatch/x"
