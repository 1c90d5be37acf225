"""Rotation-invariant classification (thesis 3.3): plain PointNet vs Compass + PointNet,
tested in canonical pose (NR) and under arbitrary rotations (AR).

The ``classification`` task (``configs/eval_classification.py``): ``run(config, workdir)``
trains one PointNet per method of ``config.methods`` (in
``workdir/<method>``; Compass-oriented shapes for ``compass+pointnet``), then scores each on
the whole test split, as is and with every shape turned by a seeded random rotation.
"""
from __future__ import annotations

import os

import jax
import ml_collections
import numpy as np

from sphere_jax import api, checks, training
from sphere_jax import bundle as bundle_files
from sphere_jax.data import augment
from sphere_jax.eval import report

METHODS = ("pointnet", "compass+pointnet")


def test_points(source, n_points, seed=0):
    """Every test shape resampled once to ``n_points`` (deterministic): ``[S, N, 3]``, labels."""
    shapes, labels = source.splits["test"]
    if not shapes:
        raise ValueError("the shape set has no test split (test.txt / modelnet40_test.txt)")
    rng = np.random.default_rng(seed)
    pts = np.stack([s[rng.choice(len(s), n_points, replace=len(s) < n_points)] for s in shapes])
    return pts.astype(np.float32), labels


def accuracy(bundle, points_SxNx3, labels, orient_shapes=None, chunk=64):
    """Fraction of shapes the classifier bundle labels correctly (turned by ``orient_shapes``
    first when given: :func:`sphere_jax.api.shape_orienter`)."""
    fwd = jax.jit(lambda x: bundle.model.apply(bundle.variables, x, train=False).logits)
    correct = 0
    for i in range(0, len(points_SxNx3), chunk):
        x = points_SxNx3[i:i + chunk]
        if orient_shapes is not None:
            x = orient_shapes(x)
        logits = np.asarray(fwd(x))
        correct += int(np.sum(np.argmax(logits, -1) == labels[i:i + chunk]))
    return correct / len(points_SxNx3)


def method_config(config, method):
    c = ml_collections.ConfigDict(config.to_dict())
    if method not in METHODS:
        raise ValueError(f"classification method must be one of {METHODS}, got {method!r}")
    c.orient_bundle = ""
    if method == "compass+pointnet":
        c.orient_bundle = config.compass_bundle
        if not bundle_files.is_bundle(c.orient_bundle):
            raise checks.MissingError(
                f"compass_bundle={c.orient_bundle!r} is not a bundle; train one with "
                f"python -m experiments.train --config=compass_shapes:mid")
        # Turned at random before Compass orients them, the training shapes show the
        # classifier the frames Compass gives rotated shapes — its errors and its choices
        # among a symmetric shape's frames included — not only those of canonical poses.
        c.data.rotate = bool(config.compass_train_rotated)
    return c


def _methods(config):
    return [m.strip() for m in config.methods.split(",") if m.strip()]


def _method_dirs(config, workdir):
    """``(method, its training workdir)`` for each method of ``config``."""
    return [(m, os.path.join(workdir, m.replace("+", "_"))) for m in _methods(config)]


def bundles(config) -> dict:
    """Kind -> path of the bundles the methods use (the run record's): the whole-shape
    Compass of ``compass+pointnet``."""
    if "compass+pointnet" not in _methods(config):
        return {}
    return {"compass_shapes": config.compass_bundle}


def kept(workdir, config) -> int:
    """How many methods' classifiers an earlier run left in ``workdir`` (trained, or to resume
    from a checkpoint): a run then is not timed from scratch (tasks.run's record)."""
    return sum(os.path.isdir(sub) for _, sub in _method_dirs(config, workdir))


def run(config, workdir, progress=True):
    """Train every method, score NR and AR; writes classification.csv / .md. Returns rows."""
    rows = []
    for method, sub in _method_dirs(config, workdir):
        c = method_config(config, method)
        orient = api.shape_orienter(c.orient_bundle) if c.orient_bundle else None
        training.train_and_evaluate(c, sub, progress, orient_shapes=orient)
        bundle = api.load_bundle(os.path.join(sub, "bundle"))
        source = training.build_source(c)
        pts, labels = test_points(source, c.data.n_points, c.seed)
        rng = np.random.default_rng(c.eval_rotation_seed)
        rotated = np.einsum("bij,bnj->bni", augment.random_rotations(rng, len(pts)), pts)
        for split, x in (("NR", pts), ("AR", rotated.astype(np.float32))):
            rows.append({"method": method, "split": split,
                         "accuracy": accuracy(bundle, x, labels, orient_shapes=orient)})
    n_test = len(labels) if rows else 0
    md = ("# Rotation-invariant classification\n\n"
          f"**Accuracy on {n_test} test shapes: NR in canonical pose, AR each turned by a seeded "
          f"random rotation (both trained in canonical pose)**\n\n"
          + report.pivot_table(rows, "method", "split", "accuracy", cols=("NR", "AR")) + "\n")
    return rows, report.write(workdir, "classification", rows, ("method", "split", "accuracy"),
                              md)
