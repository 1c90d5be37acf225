import gc
import json
import os
import re
import shutil

import jax
import numpy as np
import pytest

from configs import classify, compass, lead, lead_pn, sound
from sphere_jax import checks, models, training
from sphere_jax.data.generators import synthetic
from tests import reference
from tests.data.generators.test_synthetic import SMALL

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop

CONFIGS = {"compass": compass, "lead": lead, "lead_pn": lead_pn, "sound": sound,
           "classify": classify}


@pytest.fixture(scope="module")
def small_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("train_data")
    synthetic.make_all(str(root), seed=5, n_scenes=1, **SMALL)
    # SMALL's shape set has one training shape a class: too few to hold validation shapes out.
    synthetic.make_shapes(str(root / "shapes"), seed=5, per_class=6, n_points=500)
    return root


def tiny(name, root, **train):
    c = CONFIGS[name].get_config("tiny")
    c.data.root = str(root / ("shapes" if name == "classify" else "3dmatch"))
    c.data.val_every = 2                # a few shapes a class: every 2nd validates
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


def _fresh_steps(config):
    """``(state, batch, train_step, eval_step)``: a freshly initialised model of ``config`` and
    its first training batch."""
    source = training.build_source(config)
    model = training.training_model(config)
    tx = training.optimiser()
    batch = training.get_batch(config, source, 0)
    return (training.init_state(config, model, tx, batch), batch,
            *training.make_steps(config, model, tx))


def test_loss_decreases_on_a_fixed_batch(small_root):
    state, batch, step, _ = _fresh_steps(tiny("lead", small_root, learning_rate=3e-3))
    losses = []
    for _ in range(50):
        state, metrics = step(state, batch)
        losses.append(float(metrics["loss"]))
    assert np.mean(losses[-5:]) < 0.7 * np.mean(losses[:5])


@pytest.mark.parametrize("frozen", [False, True])
def test_frozen_batch_norm_trains_the_network_as_it_is_evaluated(small_root, frozen):
    """``train.frozen_batch_norm`` (adaptation): a step's loss is the evaluation's on the same
    batch and the running moments stay; by default batch norm uses the batch's moments and
    updates the running ones."""
    config = tiny("lead_pn", small_root)
    if frozen:
        config.train.frozen_batch_norm = True
    state, batch, step, evaluate = _fresh_steps(config)
    expected = float(evaluate(state, batch)["loss"])
    before = jax.tree_util.tree_map(np.asarray, state["batch_stats"])
    state, metrics = step(state, batch)
    moved = _max_difference(state["batch_stats"], before)
    if frozen:
        assert abs(float(metrics["loss"]) - expected) <= 1e-5 * expected and moved == 0.0
    else:
        assert abs(float(metrics["loss"]) - expected) > 1e-3 * expected and moved > 0.0


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


def test_time_budget_stops_with_a_checkpoint_and_a_bundle_that_says_so(small_root, tmp_path):
    """A budget shorter than one step ends the loop after that step: logged, checkpointed, a
    bundle recording 1 step; the same command without the budget resumes from it."""
    from sphere_jax.bundles import store
    c = tiny("lead", small_root, steps=3, log_every=2, eval_every=2, checkpoint_every=2,
             time_budget_s=1e-9)
    training.train_and_evaluate(c, str(tmp_path), progress=False)
    lines = (tmp_path / "metrics.jsonl").read_text().splitlines()
    assert [json.loads(ln)["step"] for ln in lines] == [1]
    assert "val_loss" in json.loads(lines[0])
    stopped = store.read_config(str(tmp_path / "bundle"))
    assert store.steps_done(stopped) == 1 and stopped.train.steps == 3    # done, planned
    c.train.time_budget_s = 0.0
    training.train_and_evaluate(c, str(tmp_path), progress=False)
    steps = [json.loads(ln)["step"] for ln in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert steps == [1, 2, 3]
    assert store.steps_done(store.read_config(str(tmp_path / "bundle"))) == 3


def _max_difference(tree_a, tree_b):
    """The largest absolute difference between the leaves of two pytrees of arrays."""
    a, b = jax.tree_util.tree_leaves(tree_a), jax.tree_util.tree_leaves(tree_b)
    assert a and len(a) == len(b)
    return max(float(np.abs(np.asarray(x) - np.asarray(y)).max()) for x, y in zip(a, b))


def _max_change(bundle_a, bundle_b, collection="params"):
    """The largest change of any variable of ``collection`` between two bundles."""
    from sphere_jax.bundles import inference
    return _max_difference(*(inference.load_bundle(p).variables[collection]
                             for p in (bundle_a, bundle_b)))


def test_run_continues_from_its_committed_bundle(small_root, tmp_path):
    """A fresh machine continues a run from its bundle: it starts at the bundle's step, from
    its parameters (moved by Adam steps only), and refuses a bundle of another model."""
    first = tiny("lead", small_root, steps=2, log_every=1, eval_every=4, checkpoint_every=2)
    training.train_and_evaluate(first, str(tmp_path / "a"), progress=False)
    more = tiny("lead", small_root, steps=4, log_every=1, eval_every=4, checkpoint_every=2,
                init_bundle=str(tmp_path / "a" / "bundle"))
    training.train_and_evaluate(more, str(tmp_path / "b"), progress=False)
    steps = [json.loads(ln)["step"] for ln in
             (tmp_path / "b" / "metrics.jsonl").read_text().splitlines()]
    assert steps == [3, 4]
    moved = _max_change(tmp_path / "a" / "bundle", tmp_path / "b" / "bundle")
    assert 0 < moved < 5e-3                       # two Adam steps of lr 1e-3 at most
    other = tiny("lead", small_root, steps=4, init_bundle=str(tmp_path / "a" / "bundle"))
    other.model_kwargs.features = (4, 4, 4, 2, 1)
    with pytest.raises(checks.ConfigError, match="another model_kwargs"):   # one line, exit 2
        training.train_and_evaluate(other, str(tmp_path / "c"), progress=False)
    other = tiny("lead", small_root, steps=4, init_bundle=str(tmp_path / "a" / "bundle"))
    other.data.copy_draw = "support"
    # Only the field that differs is named, not the whole data section.
    named = r"another data \({'copy_draw': 'patch'}\) than this config's \({'copy_draw': 'support'}"
    with pytest.raises(checks.ConfigError, match=named):
        training.train_and_evaluate(other, str(tmp_path / "d"), progress=False)
    # A finished workdir resumes and reads no bundle, but a mistyped one is still refused.
    more.train.init_bundle = str(tmp_path / "nowhere")
    with pytest.raises(checks.SphereJaxError, match="nowhere: not a bundle"):
        training.train_and_evaluate(more, str(tmp_path / "b"), progress=False)


def test_finetune_starts_at_step_one_from_a_bundle_with_other_data(small_root, tmp_path):
    """train.finetune_bundle: another copy draw and batch size (which init_bundle refuses),
    step 1 onwards from the bundle's weights; another network, or init_bundle as well, is a
    ConfigError."""
    first = tiny("lead", small_root, steps=2, log_every=1, eval_every=4, checkpoint_every=2)
    training.train_and_evaluate(first, str(tmp_path / "a"), progress=False)
    path = str(tmp_path / "a" / "bundle")
    tune = tiny("lead", small_root, steps=2, log_every=1, eval_every=4, checkpoint_every=2,
                finetune_bundle=path, batch_size=2)
    tune.data.copy_draw = "support"
    tune.seed = first.seed + 1                    # its own init would be far from the bundle
    training.train_and_evaluate(tune, str(tmp_path / "b"), progress=False)
    steps = [json.loads(ln)["step"] for ln in
             (tmp_path / "b" / "metrics.jsonl").read_text().splitlines()]
    assert steps == [1, 2]
    moved = _max_change(path, tmp_path / "b" / "bundle")
    assert 0 < moved < 5e-3                       # two Adam steps from the bundle, not an init
    # The same command resumes (nothing left to do); once the bundle at that path has been
    # retrained, the workdir's fine-tune of the old weights is refused, not continued.
    training.train_and_evaluate(tune, str(tmp_path / "b"), progress=False)
    first.seed += 1
    training.train_and_evaluate(first, str(tmp_path / "a2"), progress=False)
    shutil.rmtree(path)
    shutil.copytree(tmp_path / "a2" / "bundle", path)
    tune.train.steps = 3
    with pytest.raises(checks.ConfigError, match="a run from weights [0-9a-f]{16}; this run "
                                                 "starts from weights [0-9a-f]{16}"):
        training.train_and_evaluate(tune, str(tmp_path / "b"), progress=False)
    other = tiny("lead", small_root, steps=2, finetune_bundle=path)
    other.model_kwargs.features = (4, 4, 4, 2, 1)
    with pytest.raises(checks.ConfigError, match="finetune_bundle.*another model_kwargs"):
        training.train_and_evaluate(other, str(tmp_path / "c"), progress=False)
    both = tiny("lead", small_root, steps=4, finetune_bundle=path, init_bundle=path)
    with pytest.raises(checks.ConfigError, match="both set"):
        training.train_and_evaluate(both, str(tmp_path / "d"), progress=False)


def test_test_time_adaptation_starts_from_the_bundle(small_root, tmp_path, capsys):
    from experiments import adapt
    config = tiny("compass", small_root, steps=1)
    scans = config.data.root
    # Trained on weighted roots; adapted on one folder (the weights must not follow it).
    config.data.update(root=f"{scans},{scans}", root_weights="1,1")
    training.train_and_evaluate(config, str(tmp_path / "src"), progress=False)
    adapt.main([f"--bundle={tmp_path / 'src' / 'bundle'}", f"--data={scans}",
                "--steps=2", "--patience=0", f"--workdir={tmp_path / 'adapted'}"])
    moved = _max_change(tmp_path / "src" / "bundle", tmp_path / "adapted" / "bundle")
    # Two Adam steps of lr 1e-3 move each weight by at most ~2e-3: adapted, not re-initialised.
    assert 0 < moved < 5e-3
    # Without early stopping the bundle holds the last step's weights, and says so.
    assert re.search(r"adapted bundle in \S+: compass: 2 steps, validation loss [\d.]+ at the "
                     r"last step: those weights used", capsys.readouterr().out)
    # Validated on enough patches that a few flipped frames do not decide when it stops.
    from sphere_jax.bundles import store
    from sphere_jax.training import adaptation
    train = store.read_config(tmp_path / "adapted" / "bundle").train
    assert train.eval_batches * train.batch_size >= adaptation.EVAL_PATCHES >= 256
    assert train.frozen_batch_norm is False          # Compass adapts with batch moments
    # The workdir is an adaptation of those weights: the same command resumes it, while a
    # retrained bundle adapted there is refused rather than continuing the old adaptation.
    adapt.main([f"--bundle={tmp_path / 'src' / 'bundle'}", f"--data={scans}",
                "--steps=2", "--patience=0", f"--workdir={tmp_path / 'adapted'}"])
    config.seed = 1
    training.train_and_evaluate(config, str(tmp_path / "src2"), progress=False)
    with pytest.raises(SystemExit):
        adapt.main([f"--bundle={tmp_path / 'src2' / 'bundle'}", f"--data={scans}",
                    "--steps=2", "--patience=0", f"--workdir={tmp_path / 'adapted'}"])
    assert re.search("a run from weights [0-9a-f]{16}; this run starts from weights [0-9a-f]{16}",
                     capsys.readouterr().err)


def test_an_adaptation_that_never_improves_ships_the_weights_it_started_from(small_root,
                                                                              tmp_path):
    """Early stopping keeps the best evaluation's weights, and the evaluation before the first
    step counts: at a learning rate that wrecks the network, the bundle is the one it started
    from (step 0 in its log and card)."""
    from sphere_jax.bundles import inference, model_card
    config = tiny("lead", small_root, steps=1)
    training.train_and_evaluate(config, str(tmp_path / "src"), progress=False)
    trained = inference.load_bundle(tmp_path / "src" / "bundle")
    path = training.adapt(trained, config.data.root, 6, str(tmp_path / "adapted"),
                          learning_rate=1.0, progress=False, patience=2)
    log = [json.loads(ln) for ln in (tmp_path / "adapted" / "metrics.jsonl").read_text()
           .splitlines()]
    assert log[0]["step"] == 0 and "val_loss" in log[0] and "loss" not in log[0]
    assert min(ln["val_loss"] for ln in log[1:] if "val_loss" in ln) > log[0]["val_loss"]
    assert _max_change(tmp_path / "src" / "bundle", path) == 0.0
    adapted = inference.load_bundle(path)
    assert adapted.config.train.best_step == 0 and adapted.config.train.steps_done >= 2
    assert "weights of step 0" in open(f"{path}/{model_card.CARD}").read()
    from sphere_jax.training import adaptation
    assert re.fullmatch(r"lead: \d+ steps, validation loss [\d.]+ at the start and never "
                        r"lower: the starting weights kept", adaptation.outcome(path))


def test_lead_adapts_for_minutes_at_the_scale_of_the_scans(small_root, tmp_path, capsys):
    """An autoencoder adapts too: ``--minutes`` stops it (the first step's compilation alone
    outlasts 1.2 s) and the scale is chosen from the scans and printed."""
    from experiments import adapt
    from sphere_jax.bundles import inference, store
    config = tiny("lead", small_root, steps=1)
    training.train_and_evaluate(config, str(tmp_path / "src"), progress=False)
    adapt.main([f"--bundle={tmp_path / 'src' / 'bundle'}", f"--data={config.data.root}",
                "--minutes=0.02", "--steps=50", "--patience=0",
                f"--workdir={tmp_path / 'adapted'}"])
    printed = capsys.readouterr().out
    assert "adapting lead on" in printed and "voxel" in printed and "0.02 min" in printed
    adapted = inference.load_bundle(tmp_path / "adapted" / "bundle")
    assert 1 <= store.steps_done(adapted.config) < 50
    assert adapted.config.data.voxel != config.data.voxel          # chosen from the scans
    # From the bundle, not an init (the warm-up's first step has rate 0: it may not move yet).
    assert _max_change(tmp_path / "src" / "bundle", tmp_path / "adapted" / "bundle") < 5e-3
    # Fine-tuned as it is used: batch norm by the bundle's running moments, which it keeps.
    assert adapted.config.train.frozen_batch_norm is True
    assert _max_change(tmp_path / "src" / "bundle", tmp_path / "adapted" / "bundle",
                       "batch_stats") == 0.0


def test_adaptation_never_reads_the_test_scans_ground_truth(small_root, tmp_path, monkeypatch):
    """A bundle trained with copies from another scan (ground-truth poses) adapts on second
    draws of the support: the poses of the scans it adapts on are never read."""
    from sphere_jax.bundles import inference
    from sphere_jax.data import poses
    config = tiny("compass", small_root, steps=1)
    config.data.copy_draw = "scan"
    training.train_and_evaluate(config, str(tmp_path / "src"), progress=False)
    trained = inference.load_bundle(tmp_path / "src" / "bundle")

    def no_ground_truth(*_):
        raise AssertionError("adaptation read ground-truth poses")
    monkeypatch.setattr(poses, "scene_poses", no_ground_truth)
    path = training.adapt(trained, config.data.root, 1, str(tmp_path / "adapted"),
                          progress=False)
    assert inference.load_bundle(path).config.data.copy_draw == "support"
    with pytest.raises(checks.ConfigError, match="ground-truth poses"):
        training.adapt(trained, config.data.root, 1, str(tmp_path / "again"), progress=False,
                       data={"copy_draw": "scan"})


def _random_batch(config, n, seed=0):
    from sphere_jax.data import augment
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, config.data.n_points, 3))
    p = (p / np.linalg.norm(p, axis=-1).max(1)[:, None, None]).astype(np.float32)
    batch = {"patches": p}
    if models.spec(config.model).copies:
        batch.update(augment.rotated_copies(p, rng))
    return batch


def _tree_rel_err(a, b):
    """``|a - b| / |b|`` over every leaf of two trees at once: leaves whose gradient is zero
    analytically (the bias before a shift-invariant soft-argmax or batch norm) hold only
    round-off, which a per-leaf ratio would blow up."""
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    num = sum(float(np.sum((np.asarray(x) - np.asarray(y)) ** 2)) for x, y in zip(la, lb))
    return np.sqrt(num / sum(float(np.sum(np.asarray(y) ** 2)) for y in lb))


@pytest.mark.parametrize("size", ["tiny", "small"])          # 'small': bandwidth 8
@pytest.mark.parametrize("name", ["compass", "lead", "sound"])
def test_fused_training_equals_layer_by_layer(name, size):
    """Loss, gradients and new batch statistics of the spectral-domain path (the default)
    against the layer-by-layer reference on whole grids, to 1e-5 — or, where the reference's
    own gradient moves more than that when its input moves by 1e-7 (LEAD's Chamfer loss at
    'small' size: its nearest neighbours switch), to twice the largest such movement over four
    nudges. One nudge is a lottery: the reference moved 5e-6 under one and 2e-4 under the
    others, and the fused path sits 6e-5 away."""
    config = CONFIGS[name].get_config(size)
    batch = _random_batch(config, 4)
    rng = np.random.default_rng(1)
    nudges = [1 + 1e-7, 1 - 1e-7] + [1 + 1e-7 * rng.standard_normal(batch["patches"].shape)
                                     for _ in range(2)]
    got = {}
    for fused in (True, False):
        config.train.fused = fused
        model = training.training_model(config).clone(axis_name=None)
        # LEAD's bound above was measured from the eager init's values (jit's differ in the
        # 8th digit, and so do which Chamfer neighbours switch); the others init under jit.
        v = (model.init(jax.random.PRNGKey(0), batch["patches"], train=False) if name == "lead"
             else reference.init(model, batch["patches"], train=False))
        f = lambda p, b: training.loss_fn(config, model, {**v, "params": p}, b,
                                          jax.random.PRNGKey(1))
        grad = jax.jit(jax.value_and_grad(f, has_aux=True))
        got[fused] = grad(v["params"], batch)
    sensitivity = max(_tree_rel_err(grad(v["params"], {
        **batch, "patches": (batch["patches"] * k).astype(np.float32)})[1], got[False][1])
        for k in nudges)
    (loss, (_, stats)), grads = got[True]
    (ref_loss, (_, ref_stats)), ref_grads = got[False]
    assert abs(float(loss) - float(ref_loss)) <= 1e-5 * abs(float(ref_loss))
    assert _tree_rel_err(grads, ref_grads) < max(1e-5, 2 * sensitivity)
    assert _tree_rel_err(stats, ref_stats) < 1e-5


def test_first_non_finite_loss_stops_keeping_the_last_good_checkpoint(small_root, tmp_path,
                                                                       monkeypatch):
    workdir = str(tmp_path / "run")
    training.train_and_evaluate(tiny("lead", small_root, steps=2), workdir, progress=False)
    stamp = os.stat(os.path.join(workdir, "bundle", "config.json")).st_mtime_ns
    good = training.loss_fn

    def nan_loss(*args, **kwargs):
        loss, (metrics, stats) = good(*args, **kwargs)
        return loss * np.nan, (dict(metrics, loss=loss * np.nan), stats)

    monkeypatch.setattr(training.loop, "loss_fn", nan_loss)
    with pytest.raises(training.TrainingError, match="step 3: the loss is nan .* The "
                                                     "checkpoint of step 2 is kept; no bundle"):
        training.train_and_evaluate(tiny("lead", small_root, steps=4), workdir, progress=False)
    assert sorted(os.listdir(os.path.join(workdir, "checkpoints"))) == ["2"]
    assert os.stat(os.path.join(workdir, "bundle", "config.json")).st_mtime_ns == stamp


def test_unrestorable_newest_checkpoint_falls_back_to_the_one_before(small_root, tmp_path,
                                                                     unraisable_reports):
    workdir = str(tmp_path / "run")
    training.train_and_evaluate(tiny("lead", small_root, steps=4), workdir, progress=False)
    newest = os.path.join(workdir, "checkpoints", "4")
    data = max((os.path.join(d, f) for d, _, fs in os.walk(newest) for f in fs),
               key=os.path.getsize)
    with open(data, "r+b") as f:
        f.truncate(100)
    with pytest.warns(UserWarning, match="checkpoint of step 4 .* cannot be restored"):
        _, last = training.train_and_evaluate(tiny("lead", small_root, steps=6), workdir,
                                              progress=False)
    assert last["step"] == 6 and np.isfinite(last["loss"])
    assert sorted(os.listdir(os.path.join(workdir, "checkpoints")), key=int)[-1] == "6"
    assert len(os.listdir(os.path.join(workdir, "unrestorable"))) == 1      # kept, aside
    steps = [json.loads(ln)["step"] for ln in open(os.path.join(workdir, "metrics.jsonl"))]
    assert steps == [1, 2, 3, 4, 5, 6]                 # 3 and 4 redone, logged once
    gc.collect()
    assert unraisable_reports == []        # orbax's abandoned reads were collected, quietly


def test_workdir_of_another_model_is_refused(small_root, tmp_path):
    workdir = str(tmp_path / "run")
    training.train_and_evaluate(tiny("lead", small_root, steps=2), workdir, progress=False)
    with pytest.raises(checks.ConfigError, match="holds the checkpoints of model "
                                                          "lead .* this config trains compass"):
        training.train_and_evaluate(tiny("compass", small_root, steps=2), workdir,
                                    progress=False)
    os.remove(os.path.join(workdir, training.WORKDIR_CONFIG))    # a run from before the record
    with pytest.raises(checks.ConfigError, match="checkpoints of another model than "
                                                          "this config's compass"):
        training.train_and_evaluate(tiny("compass", small_root, steps=2), workdir,
                                    progress=False)


def test_a_continued_run_keeps_the_schedule_of_the_uninterrupted_one(small_root, tmp_path):
    """Warm-up and cosine decay are a function of the global step: a run stopped by its budget
    and continued on 'another machine' from its bundle logs, step for step, the learning rates
    of the uninterrupted run; a bundle trained on another schedule is refused."""
    from sphere_jax.bundles import store
    sched = dict(schedule="warmup_cosine", warmup_steps=2, final_lr_fraction=0.1, log_every=1,
                 eval_every=8, checkpoint_every=8)
    whole = tiny("lead", small_root, steps=6, **sched)
    training.train_and_evaluate(whole, str(tmp_path / "whole"), progress=False)
    rates = lambda w: {json.loads(ln)["step"]: json.loads(ln)["learning_rate"] for ln in
                       (tmp_path / w / "metrics.jsonl").read_text().splitlines()}
    first = tiny("lead", small_root, steps=6, time_budget_s=1e-9, **sched)
    training.train_and_evaluate(first, str(tmp_path / "a"), progress=False)
    assert store.steps_done(store.read_config(str(tmp_path / "a" / "bundle"))) == 1
    more = tiny("lead", small_root, steps=6, init_bundle=str(tmp_path / "a" / "bundle"), **sched)
    training.train_and_evaluate(more, str(tmp_path / "b"), progress=False)
    expected = rates("whole")
    assert expected[1] == 0.0 and max(expected.values()) == pytest.approx(1e-3)
    assert rates("b") == {s: expected[s] for s in range(2, 7)}
    other = tiny("lead", small_root, steps=6, init_bundle=str(tmp_path / "a" / "bundle"),
                 **{**sched, "warmup_steps": 3})
    with pytest.raises(checks.ConfigError, match=r"another train.warmup_steps \(2\)"):
        training.train_and_evaluate(other, str(tmp_path / "c"), progress=False)
