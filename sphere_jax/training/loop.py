"""The training loop, in the order it runs: loss, learning-rate schedule and optimiser, model and
state, the jitted data-parallel steps, then :func:`train_and_evaluate`.

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

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import optax
import orbax.checkpoint as ocp
from jax.sharding import PartitionSpec as P
from tqdm import tqdm

from sphere_jax import checks, models, parallel, workdirs
from sphere_jax.bundles import model_card, store
from sphere_jax.data.prefetch import Prefetch
from sphere_jax.training import checkpoints, warm_start
from sphere_jax.training.inputs import build_source, check_orient, check_roots, get_batch


# ----------------------------------------------------------------------------------------------
# Loss
# ----------------------------------------------------------------------------------------------

def loss_fn(config, model, variables, batch, rng, train=True, spec=None):
    """``(loss, (metrics, new batch_stats))`` for one batch; what the network reads and how its
    outputs are scored is its kind's ``spec`` (:mod:`sphere_jax.models`; looked up from
    ``config.model`` unless given)."""
    spec = spec or models.spec(config.model)
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
# Schedule, model, state, steps
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
        if int(train.warmup_steps) >= int(train.steps):       # no step would be at the peak
            raise checks.ConfigError("config.train.warmup_steps",
                                     f"below config.train.steps ({train.steps}) with the "
                                     f"warmup_cosine schedule", train.warmup_steps)
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


def init_state(config, model, tx, example, spec=None):
    key = jax.random.PRNGKey(config.seed)
    x = example[(spec or models.spec(config.model)).input_key]
    variables = jax.jit(functools.partial(model.init, train=False))(
        {"params": key, "dropout": key}, x)
    state = {"params": variables["params"], "batch_stats": variables.get("batch_stats", {}),
             "opt_state": tx.init(variables["params"]), "step": jnp.zeros((), jnp.int32)}
    return state


def make_steps(config, model, tx, mesh=None, spec=None, schedule=None):
    """Jitted ``train_step(state, batch) -> (state, metrics)`` and ``eval_step(state, batch) ->
    metrics`` over ``mesh`` (:mod:`sphere_jax.parallel`; default one device): ``state``
    replicated, ``batch`` split on its first axis (:func:`parallel.shard_batch`). ``model``:
    :func:`training_model`'s, whose batch norms average over the mesh axis. ``tx``: the
    optimiser's direction (:func:`optimiser`); the step scales it by
    :func:`learning_rate_schedule` at the state's step. ``spec`` and ``schedule``: the
    config's, where the caller has them."""
    mesh = mesh if mesh is not None else parallel.make_mesh(1)
    spec = spec or models.spec(config.model)
    schedule = schedule or learning_rate_schedule(config.train)
    rep, rows = P(), P(parallel.AXIS)
    # The outputs are replicated by construction (pmean'd gradients and metrics; batch
    # statistics from pmean'd moments). shard_map's replication typing would also ask every
    # loop inside the models (fused.pointwise's) to mark its zero-initialised carry as varying.
    shard = functools.partial(jax.shard_map, mesh=mesh, out_specs=rep, check_vma=False)

    # A fine-tune with frozen batch norm (adaptation) trains the network as it is used: batch
    # norm with the running moments, which stay as they were.
    batch_moments = not config.train.get("frozen_batch_norm", False)

    def local_grads(params, batch_stats, batch, rng):
        # Dropout masks differ per device (as they would per row on one device).
        rng = jax.random.fold_in(rng, jax.lax.axis_index(parallel.AXIS))

        def f(p):
            return loss_fn(config, model, {"params": p, "batch_stats": batch_stats}, batch, rng,
                           train=batch_moments, spec=spec)

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
        metrics = loss_fn(config, model, variables, batch, jax.random.PRNGKey(0), train=False,
                          spec=spec)
        return jax.lax.pmean(metrics[1][0], parallel.AXIS)

    def eval_step(state, batch):
        return shard(local_metrics, in_specs=(rep, rep, rows))(
            state["params"], state["batch_stats"], batch)

    return jax.jit(train_step, donate_argnums=0), jax.jit(eval_step)


def optimiser():
    """Adam's direction, without a learning rate (:func:`make_steps` applies the schedule)."""
    return optax.scale_by_adam()


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


# ----------------------------------------------------------------------------------------------
# The loop
# ----------------------------------------------------------------------------------------------

def train_and_evaluate(config: ml_collections.ConfigDict, workdir: str, progress=True,
                       init_variables=None, command=None, orient_shapes=None):
    """Train (resuming from the newest checkpoint in ``workdir``, with any device count),
    evaluate, write a bundle. ``init_variables`` (params and batch_stats, e.g. from a bundle)
    start a fresh run from trained weights (test-time adaptation), as ``train.finetune_bundle``
    does from the command line; ``train.init_bundle`` continues a bundle at its step. Returns
    the final state and the last metrics.

    ``train.early_stop_patience`` > 0 ends it once the validation loss has not improved for
    that many evaluations (and ``train.early_stop_relative`` times as many as it took to reach
    the best, and not within ``train.early_stop_grace`` evaluations; :class:`Plateau`,
    adaptation uses them), and the bundle then keeps
    the weights of the best evaluation (``train.best_step``); a fine-tune from
    ``init_variables`` is evaluated before its first step, so a run that never improves on
    them ships them unchanged.
    ``train.time_budget_s`` > 0 ends the loop early once it has run that long (a lent machine's
    minutes): the step it stops at is logged, evaluated and checkpointed like the last, and the
    bundle records the steps done, so the same command with a later budget resumes.
    ``command``: the command line, for the bundle's model card
    (:mod:`sphere_jax.bundles.model_card`). ``orient_shapes``: what turns a classifier's shapes
    into the frames of ``config.orient_bundle``
    (:func:`sphere_jax.bundles.inference.shape_orienter`; required with it)."""
    checks.config_values(config)
    spec = models.spec(config.model)                    # an unknown kind, before any work
    for field in ("init_bundle", "finetune_bundle"):     # a resumed run reads neither, but a
        if config.train.get(field):                      # wrong path is still a typo to say
            store.read_config(config.train[field])
    if config.train.get("finetune_bundle") and not config.train.get("started_from"):
        # Which weights it fine-tunes: a workdir holding a fine-tune of others (the bundle was
        # retrained since) is refused rather than resumed (checkpoints.claim_workdir).
        config = ml_collections.ConfigDict(config.to_dict())
        config.train.started_from = store.variables_digest(
            store.read_variables(config.train.finetune_bundle))
    schedule = learning_rate_schedule(config.train)     # so does a bad schedule
    check_roots(config, spec)                           # so does a data root that is not there
    check_orient(config, orient_shapes)
    with workdirs.claimed(workdir, command, primary=jax.process_index() == 0):
        return _train(config, spec, schedule, workdir, progress, init_variables, command,
                      orient_shapes)


def _train(config, spec, schedule, workdir, progress, init_variables, command, orient_shapes):
    """The loop of :func:`train_and_evaluate` on its checked ``config``, with the model kind's
    ``spec`` and the learning-rate ``schedule`` resolved once."""
    checkpoints.claim_workdir(workdir, config)
    source = build_source(config, orient_shapes, progress, spec=spec, roots_checked=True)
    if spec.labelled:
        with config.unlocked():
            config.n_classes = len(source.classes)
    mesh = parallel.make_mesh(config.train.get("devices", 0) or None)
    parallel.check_batch_size(config.train.batch_size, mesh)
    model = training_model(config)
    tx = optimiser()
    state = init_state(config, model, tx, get_batch(config, source, 0, spec=spec), spec)
    train_step, eval_step = make_steps(config, model, tx, mesh, spec, schedule)
    mngr = checkpoints.checkpoint_manager(workdir, config)
    main_host = jax.process_index() == 0          # the one that logs
    metrics_path = os.path.join(workdir, "metrics.jsonl")
    start = 0
    if mngr.latest_step() is None:                # a new run: from trained weights?
        if config.train.get("init_bundle"):
            start, init_variables = warm_start.continued_bundle(config)
        elif config.train.get("finetune_bundle"):
            init_variables = warm_start.finetuned_bundle(config)
    if init_variables is not None:                # Adam's moments start afresh
        state.update(params=init_variables["params"],
                     batch_stats=init_variables.get("batch_stats", {}),
                     opt_state=tx.init(init_variables["params"]),
                     # a continued run's schedule and dropout go on at the bundle's step
                     step=jnp.asarray(start, jnp.int32))
    state = parallel.replicate(state, mesh)
    if mngr.latest_step() is not None:
        start, state, mngr = checkpoints.restore_newest(mngr, workdir, config, state, mesh)
        if main_host:
            checkpoints.truncate_metrics(metrics_path, start)
    checkpoints.record_workdir(workdir, config)
    plateau = Plateau(int(config.train.get("early_stop_patience", 0) or 0),
                      float(config.train.get("early_stop_relative", 0) or 0),
                      int(config.train.get("early_stop_grace", 0) or 0))
    fresh_finetune = init_variables is not None and start == 0 and mngr.latest_step() is None
    if plateau.patience and fresh_finetune:
        before = dict(step=0, **evaluate(config, source, state, eval_step, mesh, spec))
        plateau.reached(before["val_loss"], state, 0)
        if main_host:
            with open(metrics_path, "a") as log:
                log.write(json.dumps(before) + "\n")
    last = {}
    t_last, seen, wait_last = time.perf_counter(), 0, 0.0
    budget, t_start = float(config.train.get("time_budget_s", 0) or 0), t_last
    # A run that the time budget ends (an adaptation for minutes) has no meaningful step total.
    open_ended = budget > 0 and bool(config.train.get("budget_ends", False))
    bar = tqdm(total=None if open_ended else config.train.steps, initial=start,
               disable=not (progress and main_host),
               desc=f"{config.model}:{config.get('size', '')}")
    make = lambda step: parallel.shard_batch(get_batch(config, source, step, spec=spec), mesh)
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
                    last.update(evaluate(config, source, state, eval_step, mesh, spec))
                    final = plateau.reached(last["val_loss"], state, done) or final
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
    kept = state
    if plateau.best_state is not None:
        kept, config.train.best_step = plateau.best_state, plateau.best_step
    path = checkpoints.save_bundle(workdir, config, kept, source.statement())
    if main_host:
        model_card.write(path, metrics_path, command)
    return state, last


class Plateau:
    """Early stopping: :meth:`reached` is True once the validation loss has not improved on
    its best for ``patience`` evaluations in a row (never with ``patience`` 0) and, with
    ``relative`` > 0, for at least ``relative`` times as many evaluations as it took to reach
    that best — a run that improved late (noisy losses, a long budget) gets as long again to
    beat it — and never within the first ``grace`` evaluations (a fine-tune's fresh optimiser
    first loses ground). With ``patience``, the best evaluation's weights are kept (a host
    copy of ``params`` and ``batch_stats``: ``best_state``, ``best_step``)."""

    def __init__(self, patience: int, relative: float = 0.0, grace: int = 0):
        self.patience, self.relative, self.grace = patience, relative, grace
        self.best, self.seen, self.best_seen = float("inf"), 0, -1      # -1: no best yet
        self.best_state, self.best_step = None, None

    @property
    def since(self) -> int:
        """Evaluations since the best one."""
        return self.seen - self.best_seen - 1

    def reached(self, val_loss: float, state=None, step=None) -> bool:
        if val_loss < self.best:
            self.best, self.best_seen = val_loss, self.seen
            if self.patience and state is not None:
                self.best_step = step
                self.best_state = jax.device_get(
                    {"params": state["params"], "batch_stats": state["batch_stats"]})
        self.seen += 1
        return bool(self.patience) and self.seen > self.grace and \
            self.since >= max(self.patience, self.relative * self.best_seen)


def evaluate(config, source, state, eval_step, mesh, spec=None):
    vals = [eval_step(state, parallel.shard_batch(
        get_batch(config, source, 10_000_000 + k, "val", spec), mesh))
        for k in range(config.train.eval_batches)]
    return {f"val_{k}": float(np.mean([v[k] for v in vals])) for k in vals[0]}
