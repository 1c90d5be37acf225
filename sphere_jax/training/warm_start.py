"""How a training run starts from a bundle: continued at its step on another machine
(``train.init_bundle``), or fine-tuned from its weights at step 0 (``train.finetune_bundle``).
"""
from __future__ import annotations

import json

import ml_collections

from sphere_jax import checks
from sphere_jax.bundles.store import read_config, read_variables, steps_done

# config.data fields added after bundles were first written, with the value those bundles
# were trained with.
DATA_ADDED = {"copy_draw": "patch", "copy_jitter": 0.0, "allow_evaluation_scenes": False}


def continued_bundle(config):
    """``(steps done, variables)`` of ``config.train.init_bundle``: a run continued on another
    machine, from the bundle the last one committed. The model and data must be the bundle's;
    the loop goes on at the bundle's step with the batches it would have drawn (they are a
    function of the step), but Adam's moments start afresh — they are not in bundles."""
    path = config.train.init_bundle
    if config.train.get("finetune_bundle"):
        raise checks.ConfigError("train.init_bundle and train.finetune_bundle are both set; a "
                                 "run either continues a bundle or fine-tunes one")
    trained = read_config(path)
    _check_same(config, trained, ("model", "model_kwargs", "data", "seed"), "init_bundle")
    # A decaying schedule is a function of the planned steps too; a constant one may be
    # extended (more steps at the same rate).
    fields = SCHEDULE if config.train.get("schedule", "constant") != "constant" else \
        ("batch_size", "learning_rate", "schedule")
    _check_same(config, trained, fields, "init_bundle", section="train")
    done = steps_done(trained)
    if done >= config.train.steps:
        raise checks.ConfigError(f"train.init_bundle={path!r} has {done} steps done; "
                                 f"train.steps={config.train.steps} must be more")
    return done, read_variables(path)


# What a continued run must share with the bundle it continues: the batches and the schedule.
SCHEDULE = ("steps", "batch_size", "learning_rate", "schedule", "warmup_steps",
            "final_lr_fraction")
# config.train fields added after bundles were first written, with the value those had.
TRAIN_ADDED = {"schedule": "constant", "warmup_steps": 0, "final_lr_fraction": 1.0}


def finetuned_bundle(config):
    """The variables of ``config.train.finetune_bundle``: a new run from step 0 that starts
    from a trained bundle's weights, with this config's data, batch size and learning rate
    (copies of another kind, larger batches). Only the network must be the bundle's."""
    path = config.train.finetune_bundle
    _check_same(config, read_config(path), ("model", "model_kwargs"), "finetune_bundle")
    return read_variables(path)


def _check_same(config, trained, keys, field, section=None):
    """ConfigError naming the first of ``keys`` (of ``section``, e.g. 'train') whose value
    differs between ``config`` and the bundle's ``trained`` config (for a section, only the
    fields that differ)."""
    path = config.train[field]
    as_dict = lambda c: json.loads(json.dumps(c.to_dict() if hasattr(c, "to_dict") else c))
    if section is not None:
        config = config[section]
        trained = ml_collections.ConfigDict({**TRAIN_ADDED, **trained[section].to_dict()})
    for key in keys:
        mine, theirs = as_dict(config.get(key)), as_dict(trained.get(key))
        if key == "data" and isinstance(theirs, dict):      # written before those fields
            theirs = {**DATA_ADDED, **theirs}
        if mine != theirs:
            if isinstance(mine, dict) and isinstance(theirs, dict):    # name the fields only
                differ = [k for k in sorted(set(mine) | set(theirs), key=str)
                          if mine.get(k) != theirs.get(k)]
                theirs = {k: theirs.get(k) for k in differ}
                mine = {k: mine.get(k) for k in differ}
            name = key if section is None else f"{section}.{key}"
            raise checks.ConfigError(f"train.{field}={path!r} was trained with another "
                                     f"{name} ({theirs!r}) than this config's ({mine!r})")
