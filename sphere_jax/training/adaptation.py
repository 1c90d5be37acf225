"""Adaptation without labels: a bundle fine-tuned on the user's own scans with its own
self-supervised loss — Compass's and SOUND's frames (test-time adaptation, thesis 3.2.1), and
the LEAD and LEAD-PN autoencoders' reconstruction. No pose and no ground truth is read: a frame's
second copy of a patch is the patch turned, occluded and resampled, or a second draw of its
own support — never another scan's view of it."""
from __future__ import annotations

import os

import ml_collections

from sphere_jax import checks, models
from sphere_jax.bundles import model_card, store
from sphere_jax.training import loop

# Without a step count, a time budget decides: the steps are capped by this.
MAX_STEPS = 1_000_000
# Why these settings, with the measurements that chose them: docs/training.md ("How the
# adaptation's settings were chosen").
# The loss on EVAL_PATCHES held-back patches, every EVAL_EVERY steps: fewer patches made
# Compass's mean angle (mostly a count of frames that flip) swing enough to stop on a lucky
# early best. A run stops once the loss has not improved for PATIENCE evaluations nor for as
# many as its best took (GROWTH 1), never within GRACE: a fresh optimiser first loses ground.
PATIENCE, GROWTH, EVAL_EVERY, GRACE = 3, 1.0, 50, 6
EVAL_PATCHES = 512
# Adam starts afresh: at the bundle's full rate its first steps wreck a trained network, so the
# rate ramps up over WARMUP steps to a tenth of the bundle's.
RATE_FRACTION, WARMUP = 0.1, 25

def data_at_scale(config, voxel, radius):
    """``config.data`` overrides for scans at another scale: ``voxel`` and ``radius`` in the
    scans' unit, keypoints as dense relative to the support as in the training of the bundle
    whose ``config`` it is."""
    d = config.data
    return dict(voxel=voxel, radius=radius, keypoint_leaf=d.keypoint_leaf * radius / d.radius)


def adaptable_kinds():
    """The model kinds trained without labels, which can adapt to unlabelled scans."""
    return [k for k, s in models.SPECS.items() if not s.labelled]


def adapt(trained, data_root, steps, workdir, learning_rate=None, progress=True, data=None,
          minutes=None, patience=PATIENCE):
    """Fine-tune bundle ``trained`` (any kind of :func:`adaptable_kinds`) with its own loss on
    the scans of ``data_root`` (folders or scan files, comma-separated, as ``data.root``) for
    ``steps`` steps or ``minutes`` of wall time (either may be None, not both); the adapted
    bundle is written to ``workdir/bundle`` (re-running resumes) and its model card lists the
    scans, evaluation scenes among them included. ``data`` overrides ``config.data`` fields
    for scans of another scale (voxel, radius, keypoint_leaf). It stops early once the
    validation loss (:data:`EVAL_PATCHES` held-back patches of the same scans) has not improved
    for ``patience`` evaluations (0: never) nor for as many as it took to reach its best.
    Returns the adapted bundle's path (:func:`outcome` says what it holds)."""
    if trained.kind not in adaptable_kinds():
        raise checks.ConfigError(f"bundle {trained.kind!r} was trained with labels; adaptation "
                                 f"is for {', '.join(adaptable_kinds())} bundles")
    if steps is None and minutes is None:
        raise checks.ConfigError("adaptation needs steps or minutes (or both)")
    budget_ends = steps is None          # minutes alone: MAX_STEPS is only a cap
    steps = MAX_STEPS if steps is None else checks.positive(steps, "steps", integer=True)
    budget_s = 0.0 if minutes is None else 60.0 * checks.positive(minutes, "minutes")
    learning_rate = checks.positive(learning_rate, "learning_rate")
    patience = checks.non_negative(patience, "patience", integer=True)
    config = ml_collections.ConfigDict(trained.config.to_dict())
    config.data.root = str(data_root)
    config.data.root_weights = ""          # the training roots' shares mean nothing here
    # Adapting to the scans one evaluates on is the point; the bundle's card names them.
    config.data.allow_evaluation_scenes = True
    config.data.update(dict(data or {}))
    # Copies from another scan read the scans' ground-truth poses; on the test scans that would
    # be supervision. A bundle trained with them adapts on second draws of the support (what
    # training does on unposed scans).
    if data and dict(data).get("copy_draw") == "scan":
        raise checks.ConfigError("adaptation cannot use copy_draw='scan': it reads the scans' "
                                 "ground-truth poses")
    if config.data.get("copy_draw") == "scan":
        config.data.copy_draw = "support"
    config.train.init_bundle = config.train.finetune_bundle = ""
    # Which weights this adapts: a workdir holding an adaptation of others is refused.
    config.train.started_from = store.variables_digest(trained.variables)
    config.train.steps = int(steps)
    config.train.update(schedule="warmup_cosine", warmup_steps=min(WARMUP, int(steps) - 1),
                        final_lr_fraction=1.0,       # after the warm-up, constant
                        learning_rate=RATE_FRACTION * float(config.train.learning_rate))
    config.train.frozen_batch_norm = models.spec(trained.kind).frozen_batch_norm
    config.train.time_budget_s = budget_s
    config.train.budget_ends = budget_ends     # the loop then shows no step total
    config.train.early_stop_patience = int(patience)
    config.train.early_stop_relative = GROWTH
    config.train.early_stop_grace = GRACE
    for key in ("steps_done", "best_step"):   # the adapted bundle records its own
        if key in config.train:
            del config.train[key]
    log_every = max(1, min(config.train.log_every, EVAL_EVERY, steps))
    config.train.log_every = log_every
    config.train.eval_every = max(1, min(EVAL_EVERY, steps)) // log_every * log_every
    config.train.eval_batches = -(-EVAL_PATCHES // int(config.train.batch_size))
    config.train.checkpoint_every = max(1, min(config.train.checkpoint_every, 4 * EVAL_EVERY,
                                               steps))
    if learning_rate:
        config.train.learning_rate = float(learning_rate)
    loop.train_and_evaluate(config, workdir, progress, init_variables=trained.variables)
    return os.path.join(workdir, "bundle")


def outcome(bundle_dir) -> str:
    """What an adaptation did, in one line, from its bundle's own log and config: the steps
    run, the validation loss at the start and at the weights the bundle kept (the last
    step's without early stopping)."""
    config = store.read_config(bundle_dir)
    steps, curves = model_card.validation_curve(
        model_card.read_metrics(os.path.join(str(bundle_dir), model_card.METRICS)))
    val, best = curves.get("val_loss") or [], config.train.get("best_step")
    done = config.train.get("steps_done")
    head = f"{config.model}: {done} steps"
    if best is None and val and steps[-1] == done:      # --patience=0: the last weights
        return f"{head}, validation loss {val[-1]:.4g} at the last step: those weights used"
    if not val or steps[0] != 0 or best not in steps:
        return head
    start, kept = val[0], val[steps.index(best)]
    if best == 0:
        return (f"{head}, validation loss {start:.4g} at the start and never lower: the "
                f"starting weights kept")
    # The step count alone would hide that a long budget ended at an early best.
    later = f", none better in the {done - best} steps after" if done and done > best else ""
    return (f"{head}, validation loss {start:.4g} -> {kept:.4g} (step {best}{later}): those "
            f"weights used")
