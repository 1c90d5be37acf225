import json
import os

import jax
import numpy as np
import pytest

from configs import classify, compass, lead, lead_pn, sound
from sphere_jax import models, training
from sphere_jax.data.generators import synthetic
from tests.data.generators.test_synthetic import SMALL

CONFIGS = {"compass": compass, "lead": lead, "lead_pn": lead_pn, "sound": sound,
           "classify": classify}


@pytest.fixture(scope="module")
def small_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("train_data")
    synthetic.make_all(str(root), seed=5, n_scenes=1, **SMALL)
    return root


def tiny(name, root, **train):
    c = CONFIGS[name].get_config("tiny")
    c.data.root = str(root / ("modelnet" if name == "classify" else "3dmatch"))
    c.data.update(voxel=0.04, radius=0.5, keypoint_leaf=0.5)
    c.train.update(train)
    return c


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_one_step_of_every_config(name, small_root, tmp_path):
    state, last = training.train_and_evaluate(tiny(name, small_root, steps=1), str(tmp_path),
                                              progress=False)
    assert int(state["step"]) == 1 and np.isfinite(last["loss"])
    assert os.path.isfile(tmp_path / "bundle" / "config.json")
    lines = (tmp_path / "metrics.jsonl").read_text().splitlines()
    assert json.loads(lines[-1])["step"] == 1 and "val_loss" in json.loads(lines[-1])


def test_loss_decreases_on_a_fixed_batch(small_root):
    config = tiny("lead", small_root)
    source = training.build_source(config)
    model = models.build(config)
    import optax
    tx = optax.adam(3e-3)
    batch = training.get_batch(config, source, 0)
    state = training.init_state(config, model, tx, batch)
    step, _ = training.make_steps(config, model, tx)
    losses = []
    for _ in range(50):
        state, metrics = step(state, batch)
        losses.append(float(metrics["loss"]))
    assert np.mean(losses[-5:]) < 0.7 * np.mean(losses[:5])


def test_resumed_training_equals_uninterrupted(small_root, tmp_path):
    full = tiny("sound", small_root, steps=4, checkpoint_every=2, eval_every=4, log_every=1)
    ref, _ = training.train_and_evaluate(full, str(tmp_path / "a"), progress=False)
    first = tiny("sound", small_root, steps=2, checkpoint_every=2, eval_every=4, log_every=1)
    training.train_and_evaluate(first, str(tmp_path / "b"), progress=False)
    resumed, _ = training.train_and_evaluate(full, str(tmp_path / "b"), progress=False)
    for a, b in zip(jax.tree_util.tree_leaves(ref), jax.tree_util.tree_leaves(resumed)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    steps = [json.loads(ln)["step"] for ln in
             (tmp_path / "b" / "metrics.jsonl").read_text().splitlines()]
    assert steps == [1, 2, 3, 4]


def test_test_time_adaptation_starts_from_the_bundle(small_root, tmp_path):
    from experiments import adapt
    from sphere_jax import api
    config = tiny("compass", small_root, steps=1)
    training.train_and_evaluate(config, str(tmp_path / "src"), progress=False)
    adapt.main([f"--bundle={tmp_path / 'src' / 'bundle'}", f"--data={config.data.root}",
                "--steps=2", f"--workdir={tmp_path / 'adapted'}"])
    before = api.load_bundle(tmp_path / "src" / "bundle").variables["params"]
    after = api.load_bundle(tmp_path / "adapted" / "bundle").variables["params"]
    diffs = [float(np.abs(np.asarray(a) - np.asarray(b)).max())
             for a, b in zip(jax.tree_util.tree_leaves(before), jax.tree_util.tree_leaves(after))]
    # Two Adam steps of lr 1e-3 move each weight by at most ~2e-3: adapted, not re-initialised.
    assert 0 < max(diffs) < 5e-3
