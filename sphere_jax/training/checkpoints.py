"""A training run's workdir: orbax checkpoints with resume (a damaged newest one is moved
aside, the one before restored), the claim that the checkpoints are this model's, the metrics
log cut back to the restored step, and the bundle written at the end."""
from __future__ import annotations

import json
import os
import time
import warnings

import jax
import orbax.checkpoint as ocp

from sphere_jax import checks, files, parallel
from sphere_jax.bundles import store


def checkpoint_manager(workdir, config):
    options = ocp.CheckpointManagerOptions(max_to_keep=config.train.keep_checkpoints,
                                           create=True, enable_async_checkpointing=False)
    return ocp.CheckpointManager(os.path.abspath(os.path.join(workdir, "checkpoints")),
                                 options=options)


WORKDIR_CONFIG = "config.json"


def claim_workdir(workdir, config):
    """Refuse a workdir whose checkpoints are another model's (restoring them would fail deep
    in orbax, or worse, succeed on a same-shaped model), or a run that started from other
    trained weights (resuming it would quietly continue those: a retrained bundle adapted or
    fine-tuned in the same folder)."""
    path = os.path.join(workdir, WORKDIR_CONFIG)
    if not (os.path.isfile(path) and os.path.isdir(os.path.join(workdir, "checkpoints"))):
        return
    with open(path) as f:
        theirs = json.load(f)
    mine = {"model": config.model, "model_kwargs": _plain(config.get("model_kwargs", {}))}
    theirs_model = {k: theirs.get(k) for k in mine}
    if theirs_model != mine:
        raise checks.ConfigError(
            f"--workdir {workdir} holds the checkpoints of model {theirs_model['model']} "
            f"{theirs_model['model_kwargs']}; this config trains {mine['model']} "
            f"{mine['model_kwargs']}: choose another workdir")
    started = _started_from(theirs)
    if started != (config.train.get("started_from") or ""):
        what = (f"a run from weights {started}" if started else
                "a run that recorded no starting weights")
        raise checks.ConfigError(
            f"--workdir {workdir} holds the checkpoints of {what}; this run starts from "
            f"weights {config.train.get('started_from') or '(none: from scratch)'}: choose "
            f"another workdir (or move that one away to start afresh)")


def started_from(workdir) -> str:
    """The digest of the trained weights the run in ``workdir`` adapted or fine-tuned
    (``train.started_from``, :func:`sphere_jax.bundles.store.variables_digest`); '' for a run from
    scratch, a continued one, or no run."""
    path = os.path.join(workdir, WORKDIR_CONFIG)
    if not os.path.isfile(path):
        return ""
    with open(path) as f:
        return _started_from(json.load(f))


def _started_from(recorded: dict) -> str:
    return recorded.get("train", {}).get("started_from") or ""


def record_workdir(workdir, config):
    """Written once the run has restored or started: what :func:`claim_workdir` checks."""
    if jax.process_index() == 0:
        store.write_json(os.path.join(workdir, WORKDIR_CONFIG), config.to_json(indent=1))


def _plain(c):
    return json.loads(json.dumps(c.to_dict() if hasattr(c, "to_dict") else c))


def restore_newest(mngr, workdir, config, state, mesh):
    """``(step, state, manager)`` from the newest checkpoint that restores. One that does not
    (a truncated file, a crash mid-write) is reported, moved to ``workdir/unrestorable/`` (kept,
    not deleted) and the one before is tried."""
    sharding = parallel.replicated(mesh)
    abstract = jax.tree_util.tree_map(
        lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=sharding), state)
    want = _shapes(abstract)
    for step in sorted(mngr.all_steps(), reverse=True):
        have = _checkpoint_shapes(workdir, step)
        if have is not None and have != want:
            diff = sorted(set(have.items()) ^ set(want.items()))[0][0]
            raise checks.ConfigError(
                f"--workdir {workdir} holds checkpoints of another model than this config's "
                f"{config.model} (step {step} differs at {diff}): choose another workdir")
        restored, reason = store.restore_quietly(
            lambda: mngr.restore(step, args=ocp.args.StandardRestore(abstract)))
        if reason is None:
            return step, restored, mngr
        warnings.warn(f"checkpoint of step {step} in {workdir} cannot be restored ({reason}); "
                      f"moved to unrestorable/{step}, trying the one before", stacklevel=2)
        if jax.process_index() == 0:
            aside = os.path.join(workdir, "unrestorable")
            os.makedirs(aside, exist_ok=True)
            os.replace(os.path.join(workdir, "checkpoints", str(step)),
                       os.path.join(aside, f"{step}-{int(time.time())}"))
        mngr.close()
        mngr = checkpoint_manager(workdir, config)
    raise checks.SphereJaxError(f"no checkpoint in {workdir}/checkpoints restores (the "
                                f"unrestorable ones are in {workdir}/unrestorable); delete the "
                                f"workdir's checkpoints to start afresh")


def _shapes(tree):
    """The model's part of a state (the optimiser's namedtuples come back from metadata as
    plain containers, with other key strings)."""
    return store.tree_shapes({part: tree[part] for part in ("params", "batch_stats")})


def _checkpoint_shapes(workdir, step):
    """Parameter path -> shape of a checkpoint's metadata; None when it is unreadable."""
    try:
        with ocp.StandardCheckpointer() as ckpt:
            meta = ckpt.metadata(os.path.join(workdir, "checkpoints", str(step), "default"))
        return _shapes(getattr(meta, "item_metadata", meta))
    except Exception:
        return None


def truncate_metrics(path, last_step):
    """Drop metric lines logged after the checkpoint we resume from (they will be redone)."""
    if not os.path.isfile(path):
        return
    with open(path) as f:
        keep = [ln for ln in f if ln.strip() and json.loads(ln)["step"] <= last_step]
    files.atomic_write(path, "".join(keep))


def save_bundle(workdir, config, state, training_data=None):
    """The inference bundle ``workdir/bundle`` (:mod:`sphere_jax.bundle`)."""
    variables = {"params": state["params"], "batch_stats": state["batch_stats"]}
    return store.save(os.path.join(workdir, "bundle"), config, variables, training_data)
