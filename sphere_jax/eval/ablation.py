"""The LEAD ablation of the seed (Table 4.5, Fig. 4.5): encoder variants — kernel grid type,
number of SO(3) layers, their input bandwidths, channels — each trained for the same budget on
the same data, then feature-match recall at a few hundred keypoints on the evaluation pairs and
the forward time of a batch of patches relative to the first variant.

For each variant in ``config.variants`` (name -> model overrides of the LEAD training config
``config.base``) the task trains a LEAD in ``workdir/variants/<name>`` (rerunning resumes
and reuses finished variants), runs the registration benchmark with it (LEAD oriented by
FLARE, as the seed's table; reused too), then times every encoder back to back, and writes
``ablation.{csv,md}`` and ``ablation_pareto.png`` — recall against relative time, the Pareto
front joined. Rerun the command on a quiet machine for the timings that go in a table.
"""
from __future__ import annotations

import json
import os
import time

import jax
import ml_collections
import numpy as np

from sphere_jax import training
from sphere_jax.bundles import inference
from sphere_jax.data.readers.io import atomic_write
from sphere_jax.eval import registration, report, tasks

COLUMNS = ("variant", "description", "params", "train_s", "forward_ms", "relative_time",
           "fmr", "inlier_ratio", "n_correct", "final_loss")


def variant_config(config, name):
    """The training config of variant ``name``: ``config.base`` with the variant's model
    overrides, the ablation's data, steps and batch."""
    v = config.variants[name]
    c = ml_collections.ConfigDict(config.base.to_dict())
    c.model_kwargs.update({k: (tuple(x) if isinstance(x, list) else x)
                           for k, x in v.model.items()})
    c.data.update(config.train_data.to_dict())
    c.train.update(steps=config.budget_steps, batch_size=config.batch_size,
                   eval_every=max(1, config.budget_steps // 4),
                   checkpoint_every=max(1, config.budget_steps // 4),
                   log_every=max(1, min(50, config.budget_steps // 4)))
    return c


def train_variant(config, name, workdir, progress=True):
    """Train (or resume, or reuse) variant ``name``; ``(bundle path, record)``."""
    vdir = os.path.join(workdir, "variants", name)
    done = os.path.join(vdir, "ablation.json")
    if os.path.isfile(done):
        with open(done) as f:
            return os.path.join(vdir, "bundle"), json.load(f)
    c = variant_config(config, name)
    start = time.perf_counter()
    _, last = training.train_and_evaluate(c, vdir, progress=progress)
    record = {"train_s": round(time.perf_counter() - start, 1),
              "final_loss": float(last.get("val_loss", last.get("loss", float("nan"))))}
    atomic_write(done, json.dumps(record).encode())
    return os.path.join(vdir, "bundle"), record


def forward_ms(bundle_path, batch, repeats=5, seed=0):
    """Median wall time (ms) of the encoder on ``batch`` random unit patches, compiled first."""
    b = inference.load_bundle(bundle_path)
    pts = np.random.default_rng(seed).normal(size=(batch, b.config.data.n_points, 3))
    pts = (pts / np.linalg.norm(pts, axis=2, keepdims=True)).astype(np.float32)
    fn = jax.jit(lambda p: b.model.apply(b.variables, p, method="encode"))
    jax.block_until_ready(fn(pts))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn(pts))
        times.append(1e3 * (time.perf_counter() - t))
    return float(np.median(times)), int(sum(np.size(x) for x in
                                            jax.tree.leaves(b.variables["params"]["encoder"])))


def pareto_front(times, recalls):
    """Indices of the variants no other is both faster and better than, fastest first."""
    order = np.argsort(times)
    front, best = [], -np.inf
    for i in order:
        if recalls[i] > best:
            front.append(int(i))
            best = recalls[i]
    return front


def plot_pareto(rows, path, title):
    plt = report.pyplot()
    t = np.array([r["relative_time"] for r in rows])
    f = np.array([r["fmr"] for r in rows])
    fig, ax = plt.subplots(figsize=(5, 3.6), dpi=120)
    ax.scatter(t, f, color="tab:blue")
    for r in rows:
        ax.annotate(r["variant"], (r["relative_time"], r["fmr"]), textcoords="offset points",
                    xytext=(4, 3), fontsize=8)
    front = pareto_front(t, f)
    ax.plot(t[front], f[front], color="tab:orange", lw=1, label="Pareto front")
    ax.set(xlabel=f"forward time relative to {rows[0]['variant']}",
           ylabel="feature-match recall", title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def evaluate_variant(config, name, bundle_path, workdir, progress=True):
    """Registration means of variant ``name`` (LEAD oriented by FLARE), computed once: a rerun
    reads ``variants/<name>/evaluation.json``."""
    done = os.path.join(workdir, "variants", name, "evaluation.json")
    if os.path.isfile(done):
        with open(done) as f:
            return json.load(f)
    ev = ml_collections.ConfigDict(config.evaluation.to_dict())
    ev.methods, ev.bundles.lead = "lead", bundle_path
    reg_rows, _ = registration.run(ev, os.path.join(workdir, "variants", name, "eval"), progress)
    mean = report.with_means(reg_rows, report.REGISTRATION_COLUMNS)[-1]
    got = {k: float(mean[k]) for k in ("fmr", "inlier_ratio", "n_correct")}
    atomic_write(done, json.dumps(got).encode())
    return got


def run(config, workdir, progress=True):
    """Train and evaluate every variant (each step reused when a rerun finds it done), then
    time every encoder back to back in this one process — timings drift between runs and
    under other load, so they are never reused; returns ``(rows, markdown)``."""
    names = list(config.variants.keys())
    if not names:
        raise ValueError("config.variants is empty")
    trained = {name: train_variant(config, name, workdir, progress) for name in names}
    scores = {name: evaluate_variant(config, name, path, workdir, progress)
              for name, (path, _) in trained.items()}
    rows = []
    for name, (path, record) in trained.items():
        ms, n_params = forward_ms(path, config.forward_batch)
        rows.append(dict(variant=name, description=config.variants[name].description,
                         params=n_params, train_s=record["train_s"], forward_ms=ms,
                         **scores[name], final_loss=record["final_loss"]))
    for r in rows:
        r["relative_time"] = r["forward_ms"] / rows[0]["forward_ms"]
    title = (f"LEAD ablation: {config.budget_steps} steps × {config.batch_size} patches each, "
             f"FMR at {config.evaluation.data.n_keypoints} keypoints")
    md = f"# {title}\n\n{report.table(rows, COLUMNS)}\n"
    report.write(workdir, "ablation", rows, COLUMNS, md)
    plot_pareto(rows, os.path.join(workdir, "ablation_pareto.png"), "LEAD ablation")
    return rows, md


TASK = tasks.Task(run=run)
