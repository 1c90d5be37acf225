"""Local-descriptor object recognition with Saliency Boost (seed 2.2.3.1, ch. 5).

A database of partial views (clouds in their object's frame, from labelled model frames);
in each test frame: [Saliency Boost: keep the points whose pixels are salient] → keypoints
(uniform sampling, or ISS) → descriptors (any method of :mod:`methods`, scaled to unit
length) → nearest model descriptor under a distance threshold → geometric consistency
grouping (Chen & Bhanu 2007, as PCL's ``GeometricConsistencyGrouping``) → a pose per group
(Kabsch) → the model projected to a 2-D box. A detection is correct if its instance is in the frame
with IoU ≥ 0.25; ranking detections by group size gives the precision–recall curve and its AUC.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from sphere_jax.data import patches
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import rgbd
from sphere_jax.data.readers.rgbd import ObjectFrame
from sphere_jax.data.poses import transform
from sphere_jax.eval import report, tasks
from sphere_jax.eval.labelled import (ModelView, build_database, instance_label,
                                      make_fragment, project_box, split_frames, unit_rows)
from sphere_jax.eval.saliency import salient_mask, spectral_residual
from sphere_jax.features import methods as method_lib
from sphere_jax.features import registry
from sphere_jax.registration.estimation import kabsch

IOU_OK = 0.25


# ---- metrics -----------------------------------------------------------------------------------

def box_iou(a, b):
    """IoU of two pixel boxes ``[u0, v0, u1, v1]`` (inclusive pixel bounds)."""
    iw = min(a[2], b[2]) - max(a[0], b[0]) + 1
    ih = min(a[3], b[3]) - max(a[1], b[1]) + 1
    if iw <= 0 or ih <= 0:
        return 0.0
    inter = iw * ih
    area = lambda r: (r[2] - r[0] + 1) * (r[3] - r[1] + 1)
    return float(inter / (area(a) + area(b) - inter))


def precision_recall(scores, correct, n_ground_truth):
    """Precision and recall as the score threshold falls through every detection's score."""
    order = np.argsort(-np.asarray(scores, float), kind="stable")
    tp = np.cumsum(np.asarray(correct, bool)[order])
    fp = np.cumsum(~np.asarray(correct, bool)[order])
    precision = tp / np.maximum(tp + fp, 1)
    recall = tp / max(n_ground_truth, 1)
    return precision, recall


def pr_auc(precision, recall):
    """Area under the precision–recall curve (trapezoids from recall 0 at the first
    detection's precision)."""
    if len(recall) == 0:
        return 0.0
    r = np.concatenate([[0.0], recall])
    p = np.concatenate([[precision[0]], precision])
    return float(np.sum((r[1:] - r[:-1]) * (p[1:] + p[:-1]) / 2))


# ---- grouping ----------------------------------------------------------------------------------

def consistency_groups(model_pts, scene_pts, resolution, min_size=3):
    """Greedy geometric consistency grouping of correspondences (row k of each array): a
    correspondence joins a group if its distances to every member agree in model and scene
    within ``resolution``. Returns lists of correspondence indices, largest first."""
    n = len(model_pts)
    if n < min_size:
        return []
    dm = np.linalg.norm(model_pts[:, None] - model_pts[None], axis=-1)
    ds = np.linalg.norm(scene_pts[:, None] - scene_pts[None], axis=-1)
    consistent = np.abs(dm - ds) < resolution
    used = np.zeros(n, bool)
    groups = []
    for seed in range(n):
        if used[seed]:
            continue
        ok = consistent[seed].copy()
        ok[seed] = False
        members = [seed]
        for cand in np.nonzero(ok & ~used)[0]:
            if ok[cand]:
                members.append(cand)
                ok &= consistent[cand]
        if len(members) >= min_size:
            used[members] = True
            groups.append(members)
    return sorted(groups, key=len, reverse=True)


# ---- database and scenes -------------------------------------------------------------------------

# ---- recognition -------------------------------------------------------------------------------

@dataclasses.dataclass
class Detection:
    frame: str
    label: str
    score: int
    box: list
    transform: np.ndarray


def recognise(frame: ObjectFrame, database: list[ModelView], describe: Callable, leaf, voxel,
              match_threshold, gc_resolution, min_group=3, saliency: Callable | None = None,
              saliency_factor=1.0, keypoints="uniform", max_depth=np.inf,
              max_correspondences=1000):
    """Detections in one frame and ``(seconds per stage, number of keypoints)``. Per model
    view only the ``max_correspondences`` closest matches are grouped (grouping is quadratic
    in their number)."""
    seconds = {}
    pts, px = frame.points()
    near = pts[:, 2] <= max_depth
    pts, px = pts[near], px[near]
    t = time.perf_counter()
    if saliency is not None:
        keep = salient_mask(saliency(frame.color), saliency_factor)[px[:, 0], px[:, 1]]
        pts = pts[keep]
    seconds["saliency"] = time.perf_counter() - t
    t = time.perf_counter()
    scene = make_fragment(pts, leaf, voxel)
    if keypoints == "iss":
        scene.keypoints = patches.iss_keypoints(scene.points)
    seconds["keypoints"] = time.perf_counter() - t
    t = time.perf_counter()
    desc = unit_rows(describe(scene))
    seconds["description"] = time.perf_counter() - t
    t = time.perf_counter()
    detections, group_time = [], 0.0
    for view in database:
        dist, nn = view.tree.query(desc, k=1)
        ok = np.nonzero(dist < match_threshold)[0]
        ok = ok[np.argsort(dist[ok], kind="stable")[:max_correspondences]]
        m = view.fragment.points[view.fragment.keypoints[nn[ok]]]
        s = scene.points[scene.keypoints[ok]]
        g0 = time.perf_counter()
        for members in consistency_groups(m, s, gc_resolution, min_group)[:3]:
            pose = kabsch(m[members], s[members])
            box = project_box(transform(view.points, pose), frame.intrinsics)
            detections.append(Detection(frame.name, view.label, len(members), box, pose))
        group_time += time.perf_counter() - g0
    seconds["matching"] = time.perf_counter() - t - group_time
    seconds["grouping"] = group_time
    # One detection per instance and frame: the best-supported.
    best = {}
    for d in detections:
        if d.label not in best or d.score > best[d.label].score:
            best[d.label] = d
    return list(best.values()), seconds, int(len(scene.keypoints))


def score_detections(detections, frames_by_name):
    """``correct`` flags (instance present and IoU ≥ 0.25) and the number of ground truths."""
    correct = []
    for d in detections:
        gt = {instance_label(i): i["box"] for i in frames_by_name[d.frame].instances}
        correct.append(d.label in gt and box_iou(d.box, gt[d.label]) >= IOU_OK)
    n_gt = sum(len(f.instances) for f in frames_by_name.values())
    return np.array(correct, bool), n_gt


# ---- the benchmark -----------------------------------------------------------------------------

STAGES = ("saliency", "keypoints", "description", "matching", "grouping")


def evaluate(test_frames, database, describers: dict, leaf, voxel, match_threshold,
             gc_resolution, min_group=3, saliency=None, saliency_factor=1.0,
             keypoints="uniform", max_depth=np.inf, progress=True):
    """Rows ``{method, boost, auc, keypoints, <stage>_s, total_s}`` plain and boosted, and the
    PR curves ``{(method, boost): (precision, recall)}``."""
    by_name = {f.name: f for f in test_frames}
    rows, curves = [], {}
    for name, describe in describers.items():
        for view in database:
            view.set_descriptors(describe(view.fragment))
        for boost in ((False, True) if saliency is not None else (False,)):
            dets, secs, kps = [], dict.fromkeys(STAGES, 0.0), []
            for fr in tqdm(test_frames, desc=f"{name}{' + boost' if boost else ''}",
                           disable=not progress):
                d, s, k = recognise(fr, database, describe, leaf, voxel, match_threshold,
                                    gc_resolution, min_group, saliency if boost else None,
                                    saliency_factor, keypoints, max_depth)
                dets += d
                kps.append(k)
                for stage, v in s.items():
                    secs[stage] += v / len(test_frames)
            correct, n_gt = score_detections(dets, by_name)
            p, r = precision_recall([d.score for d in dets], correct, n_gt)
            curves[(name, boost)] = (p, r)
            rows.append({"method": name, "boost": boost, "auc": pr_auc(p, r),
                         "detections": len(dets), "correct": int(correct.sum()),
                         "ground_truth": n_gt, "keypoints": float(np.mean(kps)),
                         **{f"{k}_s": v for k, v in secs.items()},
                         "total_s": float(sum(secs.values()))})
    return rows, curves


def run(config, workdir, progress=True):
    """Saliency Boost benchmark of ``configs/eval_recognition.py``: recognition.csv / .md,
    pr_curves.png and time_vs_auc.png."""
    d = config.data
    root = d.root or synthetic.default_root("objects", config.seed)
    frames = rgbd.read_object_frames(root)
    model_frames, test_frames = split_frames(frames, config.model_views)
    if d.max_frames:
        test_frames = test_frames[:d.max_frames]
    database = build_database(model_frames, config.leaf, d.voxel)
    bundles = tasks.bundle_paths(config)
    names = tasks.chosen_methods(config, _methods(), bundles)
    describers = {m: method_lib.descriptor(m, d.radius, bundles, d.radius / 2, config.chunk)
                  for m in names}
    rows, curves = evaluate(test_frames, database, describers, config.leaf, d.voxel,
                            config.match_threshold, config.gc_resolution, config.min_group,
                            spectral_residual, config.saliency_factor,
                            config.keypoints, config.max_depth, progress)
    columns = ("method", "boost", "auc", "detections", "correct", "ground_truth", "keypoints",
               *[f"{s}_s" for s in STAGES], "total_s")
    shown = [{**r, "method": r["method"] + (" + Saliency Boost" if r["boost"] else ""),
              "keypoints": f"{r['keypoints']:.0f}"} for r in rows]
    keys = ("method", "auc", "keypoints", *[f"{s}_s" for s in STAGES], "total_s")
    headers = ("method", "AUC", "keypoints", *[f"{s} (s)" for s in STAGES], "total (s)")
    md = (f"# Recognition with Saliency Boost ({len(test_frames)} test frames, "
          f"{len(database)} model views)\n\n{report.table(shown, keys, headers)}\n")
    report.write(workdir, "recognition", rows, columns, md)
    report.plot_recognition(rows, curves, workdir)
    return rows, md


def _methods():
    """The descriptors a database of single descriptors per keypoint can hold."""
    return tuple(m.key for m in registry.METHODS if m.kind == "descriptor" and not m.hypotheses)


TASK = tasks.Task(run=run, methods=_methods)
