"""Bundle folders: what training writes is what the API loads, with the training-data
statement beside the weights."""
import os

import jax
import numpy as np
import pytest

from configs import lead
from sphere_jax import models, paths
from sphere_jax.bundles import inference, store
from sphere_jax.models import shipped
from tests import reference


def test_save_load_round_trip_and_training_data(tmp_path):
    config = lead.get_config("tiny")
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    variables = reference.init(model, x)
    statement = {"kind": "scans", "folders": {"/data/a": 3}, "keypoints": {"train": 9}}
    path = store.save(tmp_path / "b", config, dict(variables), statement)
    assert store.is_bundle(path) and store.read_config(path).model == "lead"
    assert store.read_training_data(path) == statement
    back = store.read_variables(path)
    flat = lambda t: jax.tree_util.tree_leaves(t)
    assert all(np.array_equal(a, b) for a, b in zip(flat(back), flat(dict(variables))))
    loaded = inference.load_bundle(path)
    assert loaded.kind == "lead" and loaded.spec is models.spec("lead")
    with pytest.raises(ValueError, match="not a bundle"):
        store.read_config(tmp_path)
    # A workdir holds the run's config.json beside its bundle: the error points at the bundle.
    work = tmp_path / "w"
    store.save(work / "bundle", config, dict(variables), statement)
    (work / "config.json").write_text(open(os.path.join(path, "config.json")).read())
    with pytest.raises(ValueError, match=f"a training or adaptation workdir. its bundle is "
                                         f"{work}/bundle"):
        inference.load_bundle(work)


def test_shipped_bundles_state_what_they_were_trained_on():
    for name in shipped.SHIPPED:
        data = store.read_training_data(shipped.bundle_path(name, required=True))
        assert data["folders"], name


def test_unknown_model_kind_names_the_kinds():
    with pytest.raises(ValueError, match="config.model must be one of compass, lead, lead_pn, "
                                         "sound, classify, lrf_net; got 'pointnet2'"):
        models.spec("pointnet2")


def test_portable_labels_of_data_folders(tmp_path, monkeypatch):
    monkeypatch.setenv("SPHERE_JAX_DATA", str(tmp_path / "cache"))
    assert paths.portable(tmp_path / "cache" / "synthetic-v1-seed0" / "3dmatch") == \
        "embedded/synthetic-v1-seed0/3dmatch"
    assert paths.portable(tmp_path / "elsewhere") == str(tmp_path / "elsewhere")
    monkeypatch.setenv("SPHERE_JAX_REAL_DATA", str(tmp_path))
    (tmp_path / "3dmatch").mkdir()
    assert paths.portable(tmp_path / "3dmatch" / "x") == "shared/3dmatch/x"


def test_a_bundle_write_that_fails_leaves_the_previous_bundle(tmp_path, monkeypatch):
    """The disk fills while the weights of a new bundle are written: the error reaches the
    caller, and the folder still holds the previous bundle, whole (no temporary left)."""
    import errno

    import jax.numpy as jnp
    import ml_collections
    import numpy as np
    import orbax.checkpoint as ocp

    from sphere_jax.bundles import store
    config = ml_collections.ConfigDict({"model": "lead", "data": {"root": "a"}})
    path = tmp_path / "bundle"
    store.save(path, config, {"params": {"w": jnp.ones(3)}, "batch_stats": {}})
    save = ocp.StandardCheckpointer.save

    def full_disk(self, directory, *args, **kwargs):
        save(self, directory, *args, **kwargs)          # the files land, then the disk is full
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(ocp.StandardCheckpointer, "save", full_disk)
    config.data.root = "b"
    with pytest.raises(OSError, match="No space left"):
        store.save(path, config, {"params": {"w": jnp.zeros(3)}, "batch_stats": {}})
    monkeypatch.undo()
    assert store.read_config(path).data.root == "a"
    np.testing.assert_array_equal(store.read_variables(path)["params"]["w"], np.ones(3))
    assert sorted(os.listdir(tmp_path)) == ["bundle"]
    config.data.root = "c"                              # and a later write replaces it whole
    store.save(path, config, {"params": {"w": jnp.zeros(3)}, "batch_stats": {}})
    np.testing.assert_array_equal(store.read_variables(path)["params"]["w"], np.zeros(3))
    assert sorted(os.listdir(tmp_path)) == ["bundle"] and store.read_config(path).data.root == "c"


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path, monkeypatch):
    import errno

    from sphere_jax import files
    target = tmp_path / "table.md"
    files.atomic_write(target, "old")

    def fail(*_):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", fail)
    with pytest.raises(OSError):
        files.atomic_write(target, "new " * 1000)
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["table.md"]
