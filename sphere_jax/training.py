"""Training: model and loss per experiment, the train loop, checkpoints and bundles.

``train_and_evaluate(config, workdir)`` is what ``python -m experiments.train`` runs:
deterministic batches (a function of seed and step) built in a background thread, a jitted
data-parallel step over the devices (:mod:`sphere_jax.parallel`), a tqdm bar with loss,
patches/s and the data-wait share, metrics in ``workdir/metrics.jsonl``, orbax checkpoints every
``train.checkpoint_every`` steps with automatic resume (on any device count), and at the end an
inference bundle (``workdir/bundle``: variables + config) that :mod:`sphere_jax.api` loads.
"""
from __future__ import annotations

import functools
import json
import os
import time
import warnings

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import optax
import orbax.checkpoint as ocp
from jax.sharding import PartitionSpec as P
from tqdm import tqdm

from sphere_jax import api, bundle, checks, files, model_card, models, parallel, workdirs
from sphere_jax.data import evaluation_scenes, pipeline
from sphere_jax.data.generators import synthetic
from sphere_jax.data.prefetch import Prefetch


# ----------------------------------------------------------------------------------------------
# Loss
# ----------------------------------------------------------------------------------------------

def loss_fn(config, model, variables, batch, rng, train=True):
    """``(loss, (metrics, new batch_stats))`` for one batch; what the network reads and how its
    outputs are scored is its kind's spec (:mod:`sphere_jax.models`)."""
    spec = models.spec(config.model)
    x = spec.inputs(batch)
    rngs = {"dropout": rng}
    if train:
        out, upd = model.apply(variables, x, train=True, mutable=["batch_stats"], rngs=rngs)
    else:
        out = model.apply(variables, x, train=False, rngs=rngs)
        upd = {"batch_stats": variables["batch_stats"]}
    loss, metrics = spec.loss(out, {**batch, "inputs": x}, config)
    metrics["loss"] = loss
    return loss, (metrics, upd["batch_stats"])


# ----------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------

def build_source(config):
    d = config.data
    if models.spec(config.model).labelled or d.get("shapes", False):
        root = d.root or os.path.join(synthetic.ensure_default_data(), "modelnet")
        return pipeline.ShapeSource(root, d.n_points, config.seed,
                                    d.get("holdout_every", 0))
    allow = bool(d.get("allow_evaluation_scenes", False))
    # The entries first (before an RGB-D sequence is fused), then every scan and its origin.
    evaluation_scenes.check_training_scans(
        [pipeline.entry_path(e) for e in pipeline.root_entries(d.root)], allow)
    groups = pipeline.scan_groups(d.root)
    scans = [p for g in groups for p in g]
    evaluation_scenes.check_training_scans(
        scans + [pipeline.scan_folder_label(p) for p in scans], allow)
    return pipeline.PatchSource([p for g in groups for p in g], d.voxel, d.keypoint_leaf,
                                d.radius, d.n_points, d.min_points, d.val_fraction, config.seed,
                                groups=[k for k, g in enumerate(groups) for _ in g],
                                weights=pipeline.parse_weights(d.get("root_weights", ""),
                                                               len(groups)))


def get_batch(config, source, step, split="train"):
    spec, bs = models.spec(config.model), config.train.batch_size
    if not isinstance(source, pipeline.ShapeSource):
        return source.batch(step, bs, split, copies=spec.copies, occlusion=config.data.occlusion,
                            copy_draw=config.data.get("copy_draw", DATA_ADDED["copy_draw"]),
                            copy_jitter=config.data.get("copy_jitter", DATA_ADDED["copy_jitter"]))
    split = "test" if split == "val" else split
    if not spec.labelled:                                       # Compass on whole shapes
        return source.batch(step, bs, split, copies=spec.copies,
                            occlusion=config.data.occlusion)
    batch = source.batch(step, bs, split, rotate=config.data.get("rotate", False))
    if config.get("orient_bundle"):
        batch["points"] = api.orient_shapes(api.cached_bundle(config.orient_bundle),
                                            batch["points"])
    return batch


# ----------------------------------------------------------------------------------------------
# State, steps, checkpoints
# ----------------------------------------------------------------------------------------------

def learning_rate_schedule(train):
    """The learning rate as a function of the global step (an optax schedule): constant
    ``train.learning_rate``, or with ``train.schedule='warmup_cosine'`` a linear warm-up over
    ``train.warmup_steps`` to it and a cosine decay to ``train.final_lr_fraction`` of it at
    ``train.steps``. A function of the step alone, so a resumed or continued run (another
    machine, fresh Adam moments) goes on at the rate the uninterrupted run would have had."""
    peak = float(train.learning_rate)
    kind = train.get("schedule", "constant")
    if kind == "constant":
        return optax.constant_schedule(peak)
    if kind == "warmup_cosine":
        return optax.warmup_cosine_decay_schedule(
            0.0, peak, int(train.warmup_steps), int(train.steps),
            peak * float(train.final_lr_fraction))
    raise checks.ConfigError("config.train.schedule", "'constant' or 'warmup_cosine'", kind)


def training_model(config):
    """The module the trainer differentiates: the config's model on the path ``train.fused``
    chooses (spectral domain by default; ``False``: the layer-by-layer reference) with its batch
    norms averaging over the data-parallel axis. Same parameters as :func:`models.build`'s."""
    model = models.build(config)
    changes = {"axis_name": parallel.AXIS}
    if hasattr(model, "fused"):
        changes["fused"] = bool(config.train.get("fused", True))
    return model.clone(**changes)


def init_state(config, model, tx, example):
    key = jax.random.PRNGKey(config.seed)
    x = example[models.spec(config.model).input_key]
    variables = jax.jit(functools.partial(model.init, train=False))(
        {"params": key, "dropout": key}, x)
    state = {"params": variables["params"], "batch_stats": variables.get("batch_stats", {}),
             "opt_state": tx.init(variables["params"]), "step": jnp.zeros((), jnp.int32)}
    return state


def make_steps(config, model, tx, mesh=None):
    """Jitted ``train_step(state, batch) -> (state, metrics)`` and ``eval_step(state, batch) ->
    metrics`` over ``mesh`` (:mod:`sphere_jax.parallel`; default one device): ``state``
    replicated, ``batch`` split on its first axis (:func:`parallel.shard_batch`). ``model``:
    :func:`training_model`'s, whose batch norms average over the mesh axis. ``tx``: the
    optimiser's direction (:func:`optimiser`); the step scales it by
    :func:`learning_rate_schedule` at the state's step."""
    mesh = mesh if mesh is not None else parallel.make_mesh(1)
    schedule = learning_rate_schedule(config.train)
    rep, rows = P(), P(parallel.AXIS)
    # The outputs are replicated by construction (pmean'd gradients and metrics; batch
    # statistics from pmean'd moments). shard_map's replication typing would also ask every
    # loop inside the models (fused.pointwise's) to mark its zero-initialised carry as varying.
    shard = functools.partial(jax.shard_map, mesh=mesh, out_specs=rep, check_vma=False)

    def local_grads(params, batch_stats, batch, rng):
        # Dropout masks differ per device (as they would per row on one device).
        rng = jax.random.fold_in(rng, jax.lax.axis_index(parallel.AXIS))

        def f(p):
            return loss_fn(config, model, {"params": p, "batch_stats": batch_stats}, batch, rng)

        (_, (metrics, stats)), grads = jax.value_and_grad(f, has_aux=True)(params)
        return (jax.lax.pmean(grads, parallel.AXIS), jax.lax.pmean(metrics, parallel.AXIS),
                stats)

    def train_step(state, batch):
        rng = jax.random.fold_in(jax.random.PRNGKey(config.seed + 1), state["step"])
        grads, metrics, stats = shard(local_grads, in_specs=(rep, rep, rows, rep))(
            state["params"], state["batch_stats"], batch, rng)
        updates, opt_state = tx.update(grads, state["opt_state"], state["params"])
        lr = schedule(state["step"])
        updates = jax.tree_util.tree_map(lambda u: -lr * u, updates)
        metrics = {**metrics, "learning_rate": lr}
        return {"params": optax.apply_updates(state["params"], updates), "batch_stats": stats,
                "opt_state": opt_state, "step": state["step"] + 1}, metrics

    def local_metrics(params, batch_stats, batch):
        variables = {"params": params, "batch_stats": batch_stats}
        metrics = loss_fn(config, model, variables, batch, jax.random.PRNGKey(0), train=False)
        return jax.lax.pmean(metrics[1][0], parallel.AXIS)

    def eval_step(state, batch):
        return shard(local_metrics, in_specs=(rep, rep, rows))(
            state["params"], state["batch_stats"], batch)

    return jax.jit(train_step, donate_argnums=0), jax.jit(eval_step)


def optimiser():
    """Adam's direction, without a learning rate (:func:`make_steps` applies the schedule)."""
    return optax.scale_by_adam()


def checkpoint_manager(workdir, config):
    options = ocp.CheckpointManagerOptions(max_to_keep=config.train.keep_checkpoints,
                                           create=True, enable_async_checkpointing=False)
    return ocp.CheckpointManager(os.path.abspath(os.path.join(workdir, "checkpoints")),
                                 options=options)


WORKDIR_CONFIG = "config.json"


def claim_workdir(workdir, config):
    """Refuse a workdir whose checkpoints are another model's (restoring them would fail deep
    in orbax, or worse, succeed on a same-shaped model)."""
    path = os.path.join(workdir, WORKDIR_CONFIG)
    mine = {"model": config.model, "model_kwargs": _plain(config.get("model_kwargs", {}))}
    if os.path.isfile(path):
        with open(path) as f:
            theirs = json.load(f)
        theirs = {k: theirs.get(k) for k in mine}
        if theirs != mine and os.path.isdir(os.path.join(workdir, "checkpoints")):
            raise checks.ConfigError(
                f"--workdir {workdir} holds the checkpoints of model {theirs['model']} "
                f"{theirs['model_kwargs']}; this config trains {mine['model']} "
                f"{mine['model_kwargs']}: choose another workdir")


def record_workdir(workdir, config):
    """Written once the run has restored or started: what :func:`claim_workdir` checks."""
    if jax.process_index() == 0:
        bundle.write_json(os.path.join(workdir, WORKDIR_CONFIG), config.to_json(indent=1))


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
        restored, reason = bundle.restore_quietly(
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
    return bundle.tree_shapes({part: tree[part] for part in ("params", "batch_stats")})


def _checkpoint_shapes(workdir, step):
    """Parameter path -> shape of a checkpoint's metadata; None when it is unreadable."""
    try:
        with ocp.StandardCheckpointer() as ckpt:
            meta = ckpt.metadata(os.path.join(workdir, "checkpoints", str(step), "default"))
        return _shapes(getattr(meta, "item_metadata", meta))
    except Exception:
        return None


class TrainingError(checks.SphereJaxError):
    """Training cannot go on (a non-finite loss)."""


def check_finite(metrics, step, mngr):
    """Stop at the first non-finite loss, before anything is saved from it: the newest
    checkpoint stays the last good state and no bundle is written."""
    loss = float(metrics["loss"])
    if np.isfinite(loss):
        return
    others = ", ".join(f"{k}={float(v):.4g}" for k, v in metrics.items() if k != "loss")
    kept = mngr.latest_step()
    raise TrainingError(f"step {step}: the loss is {loss} ({others}); training stopped. "
                        + (f"The checkpoint of step {kept} is kept" if kept is not None else
                           "No checkpoint was written yet")
                        + "; no bundle was written. Lower train.learning_rate or check the data.")


def _truncate_metrics(path, last_step):
    """Drop metric lines logged after the checkpoint we resume from (they will be redone)."""
    if not os.path.isfile(path):
        return
    with open(path) as f:
        keep = [ln for ln in f if ln.strip() and json.loads(ln)["step"] <= last_step]
    files.atomic_write(path, "".join(keep))


def save_bundle(workdir, config, state, training_data=None):
    """The inference bundle ``workdir/bundle`` (:mod:`sphere_jax.bundle`)."""
    variables = {"params": state["params"], "batch_stats": state["batch_stats"]}
    return bundle.save(os.path.join(workdir, "bundle"), config, variables, training_data)


# ----------------------------------------------------------------------------------------------
# The loop
# ----------------------------------------------------------------------------------------------

def train_and_evaluate(config: ml_collections.ConfigDict, workdir: str, progress=True,
                       init_variables=None, command=None):
    """Train (resuming from the newest checkpoint in ``workdir``, with any device count),
    evaluate, write a bundle. ``init_variables`` (params and batch_stats, e.g. from a bundle)
    start a fresh run from trained weights (test-time adaptation), as ``train.finetune_bundle``
    does from the command line; ``train.init_bundle`` continues a bundle at its step. Returns
    the final state and the last metrics.

    ``train.time_budget_s`` > 0 ends the loop early once it has run that long (a lent machine's
    minutes): the step it stops at is logged, evaluated and checkpointed like the last, and the
    bundle records the steps done, so the same command with a later budget resumes.
    ``command``: the command line, for the bundle's model card (:mod:`sphere_jax.model_card`)."""
    checks.config_values(config)
    learning_rate_schedule(config.train)                # a bad schedule fails before any work
    with workdirs.claimed(workdir, command, primary=jax.process_index() == 0):
        return _train(config, workdir, progress, init_variables, command)


def _train(config, workdir, progress, init_variables, command):
    claim_workdir(workdir, config)
    source = build_source(config)
    if models.spec(config.model).labelled:
        with config.unlocked():
            config.n_classes = len(source.classes)
    mesh = parallel.make_mesh(config.train.get("devices", 0) or None)
    parallel.check_batch_size(config.train.batch_size, mesh)
    model = training_model(config)
    tx = optimiser()
    state = init_state(config, model, tx, get_batch(config, source, 0))
    train_step, eval_step = make_steps(config, model, tx, mesh)
    mngr = checkpoint_manager(workdir, config)
    main_host = jax.process_index() == 0          # the one that logs
    metrics_path = os.path.join(workdir, "metrics.jsonl")
    start = 0
    if mngr.latest_step() is None:                # a new run: from trained weights?
        if config.train.get("init_bundle"):
            start, init_variables = continued_bundle(config)
        elif config.train.get("finetune_bundle"):
            init_variables = finetuned_bundle(config)
    if init_variables is not None:                # Adam's moments start afresh
        state.update(params=init_variables["params"],
                     batch_stats=init_variables.get("batch_stats", {}),
                     opt_state=tx.init(init_variables["params"]),
                     # a continued run's schedule and dropout go on at the bundle's step
                     step=jnp.asarray(start, jnp.int32))
    state = parallel.replicate(state, mesh)
    if mngr.latest_step() is not None:
        start, state, mngr = restore_newest(mngr, workdir, config, state, mesh)
        if main_host:
            _truncate_metrics(metrics_path, start)
    record_workdir(workdir, config)
    last = {}
    t_last, seen, wait_last = time.perf_counter(), 0, 0.0
    budget, t_start = float(config.train.get("time_budget_s", 0) or 0), t_last
    bar = tqdm(total=config.train.steps, initial=start, disable=not (progress and main_host),
               desc=f"{config.model}:{config.get('size', '')}")
    make = lambda step: parallel.shard_batch(get_batch(config, source, step), mesh)
    with open(metrics_path, "a") as log, \
            Prefetch(make, range(start, config.train.steps)) as batches:
        for step, batch in batches:
            state, metrics = train_step(state, batch)
            check_finite(metrics, step + 1, mngr)              # waits for the step
            seen += config.train.batch_size
            done = step + 1
            bar.update(1)
            final = done == config.train.steps or (
                budget > 0 and time.perf_counter() - t_start >= budget)
            if done % config.train.log_every == 0 or final:
                last = {k: float(v) for k, v in metrics.items()}
                now = time.perf_counter()
                last.update(step=done, patches_per_s=round(seen / (now - t_last), 2),
                            data_wait_frac=round((batches.wait_s - wait_last) / (now - t_last), 4))
                t_last, seen, wait_last = now, 0, batches.wait_s
                if done % config.train.eval_every == 0 or final:
                    last.update(evaluate(config, source, state, eval_step, mesh))
                if main_host:
                    log.write(json.dumps(last) + "\n")
                    log.flush()
                bar.set_postfix(loss=f"{last['loss']:.4f}", pps=last["patches_per_s"],
                                wait=f"{100 * last['data_wait_frac']:.0f}%")
            if done % config.train.checkpoint_every == 0 or final:
                mngr.save(done, args=ocp.args.StandardSave(state))
            if final:
                break
    bar.close()
    mngr.wait_until_finished()
    # The bundle records the steps done (fewer than planned when the budget stopped it): a
    # continued run goes on from there on the same schedule.
    config = ml_collections.ConfigDict(config.to_dict())
    config.train.steps_done = int(last.get("step", config.train.steps))
    path = save_bundle(workdir, config, state, source.statement())
    if main_host:
        model_card.write(path, metrics_path, command)
    return state, last


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
    trained = bundle.read_config(path)
    _check_same(config, trained, ("model", "model_kwargs", "data", "seed"), "init_bundle")
    # A decaying schedule is a function of the planned steps too; a constant one may be
    # extended (more steps at the same rate).
    fields = SCHEDULE if config.train.get("schedule", "constant") != "constant" else \
        ("batch_size", "learning_rate", "schedule")
    _check_same(config, trained, fields, "init_bundle", section="train")
    done = bundle.steps_done(trained)
    if done >= config.train.steps:
        raise checks.ConfigError(f"train.init_bundle={path!r} has {done} steps done; "
                                 f"train.steps={config.train.steps} must be more")
    return done, bundle.read_variables(path)


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
    _check_same(config, bundle.read_config(path), ("model", "model_kwargs"), "finetune_bundle")
    return bundle.read_variables(path)


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


def evaluate(config, source, state, eval_step, mesh):
    vals = [eval_step(state, parallel.shard_batch(
        get_batch(config, source, 10_000_000 + k, "val"), mesh))
        for k in range(config.train.eval_batches)]
    return {f"val_{k}": float(np.mean([v[k] for v in vals])) for k in vals[0]}
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
    _, last = train_and_evaluate(config, workdir, progress, init_variables=trained.variables)
    return os.path.join(workdir, "bundle"), last
