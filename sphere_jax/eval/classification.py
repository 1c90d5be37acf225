"""Rotation-invariant classification (thesis 3.3): plain PointNet vs Compass + PointNet,
tested in canonical pose (NR) and under arbitrary rotations (AR).

The ``classification`` task (``configs/eval_classification.py``): ``run(config, workdir)``
scores each method's classifier — the shipped bundle of its recipe, or, where none is given,
one trained here (``workdir/<method>``) — on the whole test split of
:class:`~sphere_jax.data.shape_source.ShapeSource`, as is and with every shape turned by a seeded
random rotation. For the Compass methods it also measures why AR loses to NR: the share of test
shapes whose frame, turned, lands within :data:`FRAME_TOLERANCE_DEG` of the canonical shape's
(per class), and the accuracy on those shapes and on the rest.
"""
from __future__ import annotations

import json
import os

import jax
import ml_collections
import numpy as np

from sphere_jax import checks, files, training
from sphere_jax.bundles import inference, model_card
from sphere_jax.bundles import store
from sphere_jax.data import oriented
from sphere_jax.eval import report, tasks

# method -> (orients by Compass, trains on turned shapes); each a recipe in configs/.
METHODS = {"pointnet": (False, False),               # configs/classify.py
           "compass+pointnet": (True, False),        # configs/classify_compass.py
           "compass_train_rotated": (True, True)}    # configs/classify_compass_rotated.py
FRAME_TOLERANCE_DEG = 15.0
# The thesis's figures (You et al. 2018's protocol: trained in canonical pose), in %.
THESIS = {"pointnet": (88.45, 12.47), "compass+pointnet": (80.51, 72.20)}


def predicted_labels(bundle, shapes, chunk=256):
    """The classifier bundle's label of each shape ``[N, 3]`` of the list: ``[S]``."""
    fwd = jax.jit(lambda x: bundle.model.apply(bundle.variables, x, train=False).logits)
    out = []
    for i in range(0, len(shapes), chunk):
        out.append(np.argmax(np.asarray(fwd(np.stack(shapes[i:i + chunk]))), -1))
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def resampled(shapes, n_points, seed):
    """Every shape resampled once to ``n_points`` (seeded; all of them, reordered, when it has
    exactly that many)."""
    rng = np.random.default_rng(seed)
    return [s[rng.choice(len(s), n_points, replace=len(s) < n_points)].astype(np.float32)
            for s in shapes]


def method_config(config, method):
    """The training config of ``method``'s classifier: the evaluation's sizes and data, its
    orientation by ``config.compass_bundle`` and its turns."""
    if method not in METHODS:
        raise ValueError(f"classification method must be one of {tuple(METHODS)}, "
                         f"got {method!r}")
    c = ml_collections.ConfigDict(config.to_dict())
    orients, turned = METHODS[method]
    c.orient_bundle = config.compass_bundle if orients else ""
    c.data.rotate = turned
    if orients and not store.is_bundle(inference.bundle_path(c.orient_bundle)):
        raise checks.MissingError(
            f"compass_bundle={c.orient_bundle!r} is not a bundle; train one with "
            f"python -m experiments.train --config=compass_shapes:mid")
    return c


def _methods(config):
    return [m.strip() for m in config.methods.split(",") if m.strip()]


def _classifier(config, method):
    """The classifier bundle ``config.classifiers`` gives ``method`` ('' where none does)."""
    return config.get("classifiers", {}).get(method, "") or ""


def bundles(config) -> dict:
    """Name -> path of the bundles the run uses (its record's): the whole-shape Compass and
    each method's given classifier."""
    names = _methods(config)
    out = {f"classifier:{m}": _classifier(config, m) for m in names if _classifier(config, m)}
    if any(METHODS.get(m, (False,))[0] for m in names):
        out["compass_shapes"] = inference.bundle_path(config.compass_bundle)
    return out


def kept(workdir, config) -> int:
    """How many methods' classifiers an earlier run trained in ``workdir`` (a run then is not
    timed from scratch: tasks.run's record)."""
    return sum(os.path.isdir(os.path.join(workdir, m.replace("+", "_")))
               for m in _methods(config) if not _classifier(config, m))


def classifier(config, method, workdir, progress=True):
    """``(bundle, its folder)``: ``method``'s classifier, the one ``config.classifiers`` names
    (checked to be a classifier trained as the method says), else one trained with the
    evaluation's config in ``workdir/<method>``."""
    given = _classifier(config, method)
    if given:
        path = inference.bundle_path(given)
        trained = store.read_config(path)
        if trained.model != "classify" or bool(trained.get("orient_bundle")) != METHODS[method][0]:
            raise checks.ConfigError(f"config.classifiers.{method}", "a classifier bundle "
                                     "trained as the method says (oriented by Compass or not)",
                                     given)
        return inference.load_bundle(path), path
    sub = os.path.join(workdir, method.replace("+", "_"))
    c = method_config(config, method)
    orient = inference.shape_orienter(c.orient_bundle) if c.orient_bundle else None
    training.train_and_evaluate(c, sub, progress, orient_shapes=orient)
    return inference.load_bundle(os.path.join(sub, "bundle")), os.path.join(sub, "bundle")


def frame_angles(turns_Sx3x3, canonical_Sx3x3, turned_Sx3x3):
    """Angle (degrees) between Compass's frame of each turned shape and its frame of the
    canonical shape turned with it (``F(R p)`` against ``R F(p)``): 0 where Compass is
    equivariant on that shape."""
    rel = np.einsum("sji,sjk->sik", np.einsum("sij,sjk->sik", turns_Sx3x3, canonical_Sx3x3),
                    turned_Sx3x3)
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1)
    return np.degrees(np.arccos(cos))


def run(config, workdir, progress=True):
    """Score every method NR and AR; writes classification.csv / .md and frames.csv. Returns
    ``(rows, markdown)``."""
    names = _methods(config)
    for m in names:
        method_config(config, m)                      # unknown names, a missing Compass
    source = training.build_source(method_config(config, "pointnet"))
    shapes, labels = source.splits["test"]
    if not shapes:
        raise ValueError("the shape set has no test split")
    turns = oriented.seeded_turns(len(shapes), [config.eval_rotation_seed, 2])
    turned = oriented.turn(shapes, turns)
    what = {"root": source.root, "split": "test", "rule": source.split_rule()}
    views = {"NR": shapes, "AR": turned}
    in_frames, angle = {}, None
    if any(METHODS[m][0] for m in names):             # each test shape oriented once
        orienter = inference.shape_orienter(config.compass_bundle)
        found = {"NR": oriented.frames(orienter, shapes, {**what, "turns": None}, progress),
                 "AR": oriented.frames(orienter, turned,
                                       {**what, "turns": int(config.eval_rotation_seed)},
                                       progress)}
        in_frames = {k: oriented.apply(views[k], *found[k]) for k in views}
        angle = frame_angles(turns, found["NR"][1], found["AR"][1])
    rows, frame_rows, trained = [], [], []
    for method in names:
        model, path = classifier(config, method, workdir, progress)
        trained.append(training_row(method, model, path))
        n = model.config.data.n_points
        seen = in_frames if METHODS[method][0] else views
        right = {split: predicted_labels(model, resampled(view, n, config.seed)) == labels
                 for split, view in seen.items()}
        for split, ok in right.items():
            rows.append({"method": method, "split": split, "accuracy": float(ok.mean()),
                         "thesis": THESIS.get(method, (np.nan, np.nan))[split == "AR"] / 100})
        if METHODS[method][0] and not frame_rows:
            frame_rows = frame_table(angle, labels, source.classes, right["AR"], method)
    return rows, write(workdir, rows, frame_rows, trained, len(shapes), source.split_rule())


def training_row(method, model, path):
    """What ``method``'s classifier cost to train: steps × batch and the training loop's wall
    time, from its bundle's log."""
    lines = model_card.read_metrics(os.path.join(path, model_card.METRICS))
    return {"method": method, "steps": store.steps_done(model.config),
            "batch": int(model.config.train.batch_size),
            "train_min": model_card.wall_time_s(lines, model.config.train.batch_size) / 60}


def frame_table(angle_deg, labels, classes, right_ar, method):
    """Per class (and 'all'): shapes, the share whose turned frame is within tolerance, and
    ``method``'s AR accuracy on those and on the rest."""
    out = []
    for c, name in [(None, "all")] + list(enumerate(classes)):
        m = np.ones(len(labels), bool) if c is None else labels == c
        if not m.any():
            continue
        good = m & (angle_deg <= FRAME_TOLERANCE_DEG)
        bad = m & ~good
        out.append({"class": name, "shapes": int(m.sum()), "frame_within": float(good.sum()
                                                                                / m.sum()),
                    "median_angle": float(np.median(angle_deg[m])),
                    "ar_accuracy_within": float(right_ar[good].mean()) if good.any() else
                    float("nan"),
                    "ar_accuracy_beyond": float(right_ar[bad].mean()) if bad.any() else
                    float("nan"), "method": method})
    return out


FACTS = "classification.json"      # the test set: how many shapes, the split's rule
FRAME_COLUMNS = ("class", "shapes", "frame_within", "median_angle", "ar_accuracy_within",
                 "ar_accuracy_beyond")


def write(workdir, rows, frame_rows, trained, n_test, rule):
    """classification.csv (accuracy per method and split), training.csv, frames.csv and
    classification.json in ``workdir``; returns :func:`summary` of them (also written as
    classification.md)."""
    os.makedirs(workdir, exist_ok=True)
    files.atomic_write(os.path.join(workdir, "training.csv"),
                       report.to_csv(trained, ("method", "steps", "batch", "train_min")))
    if frame_rows:
        files.atomic_write(os.path.join(workdir, "frames.csv"),
                           report.to_csv(frame_rows, ("method",) + FRAME_COLUMNS))
    files.atomic_write(os.path.join(workdir, FACTS),
                       json.dumps({"test_shapes": n_test, "rule": rule}, indent=1))
    files.atomic_write(os.path.join(workdir, "classification.csv"),
                       report.to_csv(rows, ("method", "split", "accuracy", "thesis")))
    md = summary(workdir)
    files.atomic_write(os.path.join(workdir, "classification.md"), md)
    return md


def _numbers(rows):
    """CSV rows with their numbers parsed: counts as ints, the rest as floats (NaN: empty)."""
    def parse(v):
        if v.lstrip("-").isdigit():
            return int(v)
        value = report.number(v)
        return float("nan") if value is None else value
    return [{k: v if k in ("method", "class", "split") else parse(v) for k, v in r.items()}
            for r in rows]


def summary(folder) -> str:
    """A run's markdown from its files (the workdir or its record in docs/records): accuracy
    NR / AR beside the thesis's, each classifier's training, and where AR loses to NR."""
    with open(os.path.join(str(folder), FACTS)) as f:
        facts = json.load(f)
    acc = {(r["method"], r["split"]): r
           for r in _numbers(report.read_rows(folder, "classification"))}
    table = [{"method": m, "NR": acc[(m, "NR")]["accuracy"], "AR": acc[(m, "AR")]["accuracy"],
              "thesis NR": acc[(m, "NR")]["thesis"], "thesis AR": acc[(m, "AR")]["thesis"]}
             for m in dict.fromkeys(m for m, _ in acc)]
    md = ("# Rotation-invariant classification\n\n"
          f"**Accuracy on {facts['test_shapes']} test shapes ({facts['rule']}): NR in canonical "
          f"pose, AR each turned by a seeded random rotation; beside them the thesis's figures "
          f"(You et al. 2018's split of ModelNet40)**\n\n"
          + report.table(table, ("method", "NR", "AR", "thesis NR", "thesis AR")))
    trained = _numbers(report.read_rows(folder, "training"))
    md += ("\n\n**Training each classifier** (the loop's wall time; orienting the shapes "
           "once is not in it)\n\n"
           + report.table(trained, ("method", "steps", "batch", "train_min"),
                          ("method", "steps", "batch", "training, min"), fmt="{:.0f}"))
    frame_rows = _numbers(report.read_rows(folder, "frames"))
    if frame_rows:
        order = [frame_rows[0]] + sorted(frame_rows[1:], key=lambda r: r["frame_within"])
        md += (f"\n\n**Where AR loses to NR: the share of test shapes whose Compass frame, "
               f"turned with the shape, lands within {FRAME_TOLERANCE_DEG:.0f}° of the "
               f"canonical shape's, per class (worst first), and {frame_rows[0]['method']}'s "
               f"AR accuracy on those shapes and on the rest**\n\n"
               + report.table(order, FRAME_COLUMNS, ("class", "shapes", "frame within",
                                                     "median angle °", "AR acc. within",
                                                     "AR acc. beyond"), fmt="{:.2f}"))
    return md + "\n"


TASK = tasks.Task(run=run, methods=lambda: tuple(METHODS), kept=kept, bundles=bundles,
                  summary=summary)
