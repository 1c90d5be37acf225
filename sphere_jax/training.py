"""Training: model and loss per experiment, the train loop, checkpoints and bundles.

``train_and_evaluate(config, workdir)`` is what ``python -m experiments.train`` runs:
deterministic batches (a function of seed and step), a jitted step, a tqdm bar with loss and
patches/s, metrics in ``workdir/metrics.jsonl``, orbax checkpoints every
``train.checkpoint_every`` steps with automatic resume, and at the end an inference bundle
(``workdir/bundle``: variables + config) that :mod:`sphere_jax.api` loads.
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
from tqdm import tqdm

from sphere_jax import losses, lrf, models
from sphere_jax.data import pipeline, synthetic

PATCH_MODELS = ("compass", "lead", "lead_pn", "sound")


# ----------------------------------------------------------------------------------------------
# Models and losses
# ----------------------------------------------------------------------------------------------

def build_model(config):
    kw = dict(config.model_kwargs)
    if config.model == "compass":
        return models.Compass(**kw)
    if config.model == "lead":
        return models.Lead(**kw)
    if config.model == "lead_pn":
        return models.LeadPN(**kw)
    if config.model == "sound":
        return models.Sound(**kw)
    if config.model == "classify":
        return models.PointNetClassifier(n_classes=config.n_classes, **kw)
    raise ValueError(f"unknown model {config.model!r}")


def loss_fn(config, model, variables, batch, rng, train=True):
    """``(loss, (metrics, new batch_stats))`` for one batch."""
    def apply(x, **kw):
        out = model.apply(variables, x, train=train, mutable=["batch_stats"] if train else False,
                          **kw)
        return out if train else (out, {"batch_stats": variables["batch_stats"]})

    m = config.model
    if m in ("compass", "sound"):
        b = batch["patches"].shape[0]
        out, upd = apply(jnp.concatenate([batch["patches"], batch["copies"]]))
        rot = out[0]
        angular = losses.geodesic_loss(rot[b:], batch["rotations"] @ rot[:b])
        metrics = {"angular": angular}
        loss = angular
        if m == "sound":
            chamfer = jnp.mean(losses.chamfer_distance(out[2][:b], batch["patches"]))
            metrics["chamfer"] = chamfer
            loss = config.loss.chamfer_weight * chamfer + config.loss.angular_weight * angular
    elif m in ("lead", "lead_pn"):
        x = batch["patches"] if m == "lead" else lrf.flare_orient(batch["patches"])
        out, upd = apply(x)
        loss = jnp.mean(losses.chamfer_distance(out[1], x))
        metrics = {"chamfer": loss}
    elif m == "classify":
        logits, upd = apply(batch["points"], rngs={"dropout": rng})
        loss = jnp.mean(optax.softmax_cross_entropy_with_integer_labels(logits, batch["labels"]))
        metrics = {"accuracy": jnp.mean(jnp.argmax(logits, -1) == batch["labels"])}
    else:
        raise ValueError(f"unknown model {m!r}")
    metrics["loss"] = loss
    return loss, (metrics, upd["batch_stats"])


# ----------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------

def build_source(config):
    d = config.data
    if config.model == "classify" or d.get("shapes", False):
        root = d.root or os.path.join(synthetic.ensure_default_data(), "modelnet")
        return pipeline.ShapeSource(root, d.n_points, config.seed)
    return pipeline.PatchSource(pipeline.scan_paths(d.root), d.voxel, d.keypoint_leaf, d.radius,
                                d.n_points, d.min_points, d.val_fraction, config.seed)


def get_batch(config, source, step, split="train"):
    bs = config.train.batch_size
    if isinstance(source, pipeline.ShapeSource):
        split = "test" if split == "val" else split
        if config.model != "classify":                        # Compass on whole shapes
            return source.batch(step, bs, split, copies=True, occlusion=config.data.occlusion)
        batch = source.batch(step, bs, split, rotate=config.data.get("rotate", False))
        if config.get("orient_bundle"):
            from sphere_jax import api
            batch["points"] = orient_shapes(api.cached_bundle(config.orient_bundle),
                                            batch["points"])
        return batch
    return source.batch(step, bs, split, copies=config.model in ("compass", "sound"),
                        occlusion=config.data.occlusion)


def orient_shapes(bundle, shapes_BxNx3):
    """Shapes turned into the canonical frame a Compass bundle (trained on whole shapes)
    gives them: ``(p − centre) @ F``, in the shapes' own units."""
    shapes_BxNx3 = np.asarray(shapes_BxNx3, np.float32)
    n = bundle.config.data.n_points
    rng = np.random.default_rng(0)
    pick = rng.integers(0, shapes_BxNx3.shape[1], n)            # the network's point count
    unit, centres = pipeline.unit_shapes(shapes_BxNx3)
    frames = np.asarray(bundle.orient_patches(unit[:, pick], chunk=min(len(unit), 256)))
    return np.einsum("bnk,bkj->bnj", shapes_BxNx3 - centres, frames).astype(np.float32)


# ----------------------------------------------------------------------------------------------
# State, steps, checkpoints
# ----------------------------------------------------------------------------------------------

def init_state(config, model, tx, example):
    key = jax.random.PRNGKey(config.seed)
    x = example["points"] if config.model == "classify" else example["patches"]
    variables = jax.jit(functools.partial(model.init, train=False))(
        {"params": key, "dropout": key}, x)
    state = {"params": variables["params"], "batch_stats": variables.get("batch_stats", {}),
             "opt_state": tx.init(variables["params"]), "step": jnp.zeros((), jnp.int32)}
    return state


def make_steps(config, model, tx):
    def train_step(state, batch):
        rng = jax.random.fold_in(jax.random.PRNGKey(config.seed + 1), state["step"])
        variables = {"params": state["params"], "batch_stats": state["batch_stats"]}

        def f(params):
            return loss_fn(config, model, {**variables, "params": params}, batch, rng)

        (_, (metrics, stats)), grads = jax.value_and_grad(f, has_aux=True)(state["params"])
        updates, opt_state = tx.update(grads, state["opt_state"], state["params"])
        return {"params": optax.apply_updates(state["params"], updates), "batch_stats": stats,
                "opt_state": opt_state, "step": state["step"] + 1}, metrics

    def eval_step(state, batch):
        variables = {"params": state["params"], "batch_stats": state["batch_stats"]}
        return loss_fn(config, model, variables, batch, jax.random.PRNGKey(0), train=False)[1][0]

    return jax.jit(train_step), jax.jit(eval_step)


def checkpoint_manager(workdir, config):
    options = ocp.CheckpointManagerOptions(max_to_keep=config.train.keep_checkpoints,
                                           create=True, enable_async_checkpointing=False)
    return ocp.CheckpointManager(os.path.abspath(os.path.join(workdir, "checkpoints")),
                                 options=options)


def _truncate_metrics(path, last_step):
    """Drop metric lines logged after the checkpoint we resume from (they will be redone)."""
    if not os.path.isfile(path):
        return
    with open(path) as f:
        keep = [ln for ln in f if ln.strip() and json.loads(ln)["step"] <= last_step]
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.writelines(keep)
    os.replace(tmp, path)


def save_bundle(workdir, config, state):
    """Inference bundle: ``bundle/variables`` (orbax) and ``bundle/config.json``."""
    path = os.path.abspath(os.path.join(workdir, "bundle"))
    os.makedirs(path, exist_ok=True)
    variables = {"params": state["params"], "batch_stats": state["batch_stats"]}
    with ocp.StandardCheckpointer() as ckpt:
        target = os.path.join(path, "variables")
        if os.path.exists(target):
            import shutil
            shutil.rmtree(target)
        ckpt.save(target, variables)
    tmp = os.path.join(path, "config.json.tmp")
    with open(tmp, "w") as f:
        f.write(config.to_json(indent=1))
    os.replace(tmp, os.path.join(path, "config.json"))
    return path


# ----------------------------------------------------------------------------------------------
# The loop
# ----------------------------------------------------------------------------------------------

def train_and_evaluate(config: ml_collections.ConfigDict, workdir: str, progress=True,
                       init_variables=None):
    """Train (resuming from the newest checkpoint in ``workdir``), evaluate, write a bundle.
    ``init_variables`` (params and batch_stats, e.g. from a bundle) start a fresh run from
    trained weights (test-time adaptation). Returns the final state and the last metrics."""
    os.makedirs(workdir, exist_ok=True)
    source = build_source(config)
    if config.model == "classify":
        with config.unlocked():
            config.n_classes = len(source.classes)
    model = build_model(config)
    tx = optax.adam(config.train.learning_rate)
    state = init_state(config, model, tx, get_batch(config, source, 0))
    if init_variables is not None:
        state.update(params=init_variables["params"],
                     batch_stats=init_variables.get("batch_stats", {}),
                     opt_state=tx.init(init_variables["params"]))
    train_step, eval_step = make_steps(config, model, tx)
    mngr = checkpoint_manager(workdir, config)
    metrics_path = os.path.join(workdir, "metrics.jsonl")
    start = 0
    if mngr.latest_step() is not None:
        start = mngr.latest_step()
        abstract = jax.tree_util.tree_map(ocp.utils.to_shape_dtype_struct, state)
        state = mngr.restore(start, args=ocp.args.StandardRestore(abstract))
        _truncate_metrics(metrics_path, start)
    last = {}
    t_last, seen = time.perf_counter(), 0
    bar = tqdm(range(start, config.train.steps), initial=start, total=config.train.steps,
               disable=not progress, desc=f"{config.model}:{config.get('size', '')}")
    with open(metrics_path, "a") as log:
        for step in bar:
            batch = get_batch(config, source, step)
            state, metrics = train_step(state, batch)
            seen += config.train.batch_size
            done = step + 1
            if done % config.train.log_every == 0 or done == config.train.steps:
                now = time.perf_counter()
                last = {k: float(v) for k, v in metrics.items()}
                last.update(step=done, patches_per_s=round(seen / (now - t_last), 2))
                t_last, seen = now, 0
                if done % config.train.eval_every == 0 or done == config.train.steps:
                    last.update(evaluate(config, source, state, eval_step))
                log.write(json.dumps(last) + "\n")
                log.flush()
                bar.set_postfix(loss=f"{last['loss']:.4f}", pps=last["patches_per_s"])
            if done % config.train.checkpoint_every == 0 or done == config.train.steps:
                mngr.save(done, args=ocp.args.StandardSave(state))
    mngr.wait_until_finished()
    save_bundle(workdir, config, state)
    return state, last


def evaluate(config, source, state, eval_step):
    vals = [eval_step(state, get_batch(config, source, 10_000_000 + k, "val"))
            for k in range(config.train.eval_batches)]
    return {f"val_{k}": float(np.mean([v[k] for v in vals])) for k in vals[0]}


def adapt(bundle, data_root, steps, workdir, learning_rate=None, progress=True):
    """Test-time adaptation (thesis 3.2.1): fine-tune a Compass or SOUND ``bundle`` with its own
    self-supervised loss on the scans under ``data_root``; the adapted bundle is written to
    ``workdir/bundle`` (re-running resumes). Returns ``(path, last metrics)``."""
    if bundle.kind not in ("compass", "sound"):
        raise ValueError(f"test-time adaptation is for compass and sound bundles, not "
                         f"{bundle.kind!r}")
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    config = ml_collections.ConfigDict(bundle.config.to_dict())
    config.data.root = str(data_root)
    config.train.steps = int(steps)
    for key in ("checkpoint_every", "eval_every", "log_every"):
        config.train[key] = max(1, min(config.train[key], steps))
    if learning_rate:
        config.train.learning_rate = float(learning_rate)
    _, last = train_and_evaluate(config, workdir, progress, init_variables=bundle.variables)
    return os.path.join(workdir, "bundle"), last
