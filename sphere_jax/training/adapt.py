"""Test-time adaptation (thesis 3.2.1): a bundle fine-tuned on unlabelled scans with its own
self-supervised loss."""
from __future__ import annotations

import os

import ml_collections

from sphere_jax import checks, models
from sphere_jax.training import loop


def adapt(trained, data_root, steps, workdir, learning_rate=None, progress=True, data=None):
    """Test-time adaptation (thesis 3.2.1): fine-tune a Compass or SOUND bundle ``trained``
    with its own self-supervised loss on the scans under ``data_root`` (never their ground
    truth: 'scan' copies become 'support' copies); the adapted bundle is
    written to ``workdir/bundle`` (re-running resumes). ``data`` overrides ``config.data``
    fields for scans of another scale (voxel, radius, keypoint_leaf). Returns
    ``(path, last metrics)``."""
    if models.spec(trained.kind).orient is None:
        able = [k for k, s in models.SPECS.items() if s.orient is not None]
        raise ValueError(f"test-time adaptation is for {' and '.join(able)} bundles, not "
                         f"{trained.kind!r}")
    steps = checks.positive(steps, "steps", integer=True)
    learning_rate = checks.positive(learning_rate, "learning_rate")
    config = ml_collections.ConfigDict(trained.config.to_dict())
    config.data.root = str(data_root)
    config.data.root_weights = ""          # the training roots' shares mean nothing here
    config.data.update(dict(data or {}))
    # Copies from another scan read the scans' ground-truth poses; on the test scans that would
    # be supervision. A bundle trained with them adapts on second draws of the support (what
    # training does on unposed scans).
    if data and dict(data).get("copy_draw") == "scan":
        raise checks.ConfigError("test-time adaptation cannot use copy_draw='scan': it reads "
                                 "the test scans' ground-truth poses")
    if config.data.get("copy_draw") == "scan":
        config.data.copy_draw = "support"
    config.train.init_bundle = config.train.finetune_bundle = ""
    config.train.steps = int(steps)
    config.train.schedule = "constant"     # a short fine-tune at the bundle's peak rate
    if "steps_done" in config.train:          # the adapted bundle records its own
        del config.train["steps_done"]
    for key in ("checkpoint_every", "eval_every", "log_every"):
        config.train[key] = max(1, min(config.train[key], steps))
    if learning_rate:
        config.train.learning_rate = float(learning_rate)
    _, last = loop.train_and_evaluate(config, workdir, progress,
                                      init_variables=trained.variables)
    return os.path.join(workdir, "bundle"), last
