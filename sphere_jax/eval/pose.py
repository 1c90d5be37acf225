"""Object pose from an RGB-D frame (seed ch. 7): box → crop → classify → choose among stored
views → FPFH → RANSAC (:mod:`sphere_jax.registration`) or FGR (open3d) → point-to-plane ICP.

A model is a set of stored partial views of one object, each a cloud in the object's frame.
:func:`estimate_pose` returns the object-to-camera transform with the ICP inlier ratio
(fitness) and RMSE, and the seconds each stage took (the seed's Tables 7.5–7.6).
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable, Sequence

import numpy as np
from scipy.spatial import cKDTree
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from tqdm.auto import tqdm

from sphere_jax.data import o3d_convert
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import rgbd
from sphere_jax.eval import labelled, registration, report, tasks
from sphere_jax.eval.objects import hsv_histogram
from sphere_jax.features import descriptors
from sphere_jax.registration.estimation import point_to_plane_icp, ransac
from sphere_jax.registration.fragments import fragment
from sphere_jax.registration.matching import mutual_matches

METHODS = ("ransac", "fgr")                 # the coarse registration
ICP_ITERATIONS = 60                         # a partial view's ICP converges more slowly


@dataclasses.dataclass
class ObjectModel:
    """Stored partial views ``[N_v, 3]`` of one object, all in the object's frame."""
    name: str
    category: str
    views: Sequence[np.ndarray]


@dataclasses.dataclass
class PoseResult:
    transform: np.ndarray           # object -> camera, 4x4
    model: str
    view: int
    fitness: float                  # ICP inlier ratio
    rmse: float                     # ICP inlier RMSE (m)
    seconds: dict                   # stage -> seconds

    @property
    def fps(self):
        return 1.0 / max(sum(self.seconds.values()), 1e-9)


def crop_box(depth, intrinsics, box, depth_scale=1000.0, color=None):
    """Points (camera frame) of the pixels inside ``box = [u0, v0, u1, v1]`` (inclusive)."""
    u0, v0, u1, v1 = (int(round(x)) for x in box)
    h, w = np.asarray(depth).shape
    u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, w - 1), min(v1, h - 1)
    if u1 < u0 or v1 < v0:
        raise ValueError(f"box {box} lies outside the {w}x{h} image")
    crop = np.asarray(depth)[v0:v1 + 1, u0:u1 + 1]
    col = None if color is None else np.asarray(color)[v0:v1 + 1, u0:u1 + 1]
    return rgbd.depth_to_cloud(crop, intrinsics, col, depth_scale=depth_scale,
                                   origin=(u0, v0))


def remove_support_plane(points, distance=0.01, min_fraction=0.3, seed=0):
    """Drop the dominant plane (a table) if it holds at least ``min_fraction`` of the points
    and something is left (a box-shaped object seen face-on is itself mostly one plane)."""
    import open3d as o3d
    if len(points) < 50:
        return points
    o3d.utility.random.seed(int(seed))
    pcd = o3d_convert.point_cloud(points)
    _, inliers = pcd.segment_plane(distance, 3, 200)
    if len(inliers) < min_fraction * len(points) or len(points) - len(inliers) < 30:
        return points
    keep = np.ones(len(points), bool)
    keep[inliers] = False
    return points[keep]


@dataclasses.dataclass
class Coarse:
    transformation: np.ndarray      # source -> target, 4x4
    fitness: float                  # share of source points within the distance of the target


def _features(points, voxel):
    """``(fragment, FPFH [N, 33])``: the voxelised cloud, its normals turned to the camera
    (at the origin) and every point's FPFH (five voxels wide)."""
    frag = fragment("view", points, voxel, np.random.default_rng(0), n_keypoints=len(points),
                    viewpoint=(0.0, 0.0, 0.0))            # every point a keypoint
    return frag, descriptors.fpfh(frag.points, frag.normals, frag.keypoints, 5 * voxel)


def _fitness(src, dst, t, distance):
    moved = src.points @ t[:3, :3].T + t[:3, 3]
    return float(np.mean(dst.tree.query(moved, k=1)[0][:, 0] < distance))


def global_registration(src, src_fpfh, dst, dst_fpfh, voxel, method="ransac", seed=0,
                        iterations=100_000) -> Coarse:
    """Coarse ``T`` with ``dst ≈ T src`` from FPFH matches: the registration library's RANSAC
    on mutual matches, or open3d's Fast Global Registration."""
    dist = 1.5 * voxel
    if method == "fgr":
        import open3d as o3d
        reg = o3d.pipelines.registration
        t = np.asarray(reg.registration_fgr_based_on_feature_matching(
            o3d_convert.point_cloud(src.points), o3d_convert.point_cloud(dst.points),
            o3d_convert.feature(src_fpfh), o3d_convert.feature(dst_fpfh),
            reg.FastGlobalRegistrationOption(maximum_correspondence_distance=dist))
            .transformation)
    elif method == "ransac":
        ia, ib = mutual_matches(src_fpfh, dst_fpfh)
        t = ransac(dst.points[ib], src.points[ia], dist, iterations, seed)
    else:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    return Coarse(t, _fitness(src, dst, t, dist))


def estimate_pose(depth, intrinsics, box, models: Sequence[ObjectModel], voxel=0.01,
                  classify: Callable | None = None, color=None, method="ransac",
                  depth_scale=1000.0, seed=0) -> PoseResult:
    """The whole pipeline on one detection. ``classify(points, color_crop) -> category``
    narrows the candidate models (all models when None)."""
    seconds = {}
    t = time.perf_counter()
    cloud = crop_box(depth, intrinsics, box, depth_scale, color)
    points = remove_support_plane(cloud.points, 1.5 * voxel, seed=seed)
    seconds["crop"] = time.perf_counter() - t
    t = time.perf_counter()
    candidates = list(models)
    if classify is not None:
        category = classify(points, color)
        candidates = [m for m in models if m.category == category] or candidates
    seconds["classify"] = time.perf_counter() - t
    t = time.perf_counter()
    scene, scene_fpfh = _features(points, voxel)
    views = [(m, v, _features(np.asarray(view, np.float32), voxel))
             for m in candidates for v, view in enumerate(m.views)]
    seconds["fpfh"] = time.perf_counter() - t
    t = time.perf_counter()
    best = None
    for m, v, (src, src_fpfh) in views:                        # choose the view that fits best
        coarse = global_registration(src, src_fpfh, scene, scene_fpfh, voxel, method, seed)
        if best is None or coarse.fitness > best[0].fitness:
            best = (coarse, m, v, src)
    seconds["global"] = time.perf_counter() - t
    t = time.perf_counter()
    coarse, m, v, src = best
    t_fine, fitness, rmse = point_to_plane_icp(src, scene, coarse.transformation, voxel,
                                               ICP_ITERATIONS)
    seconds["icp"] = time.perf_counter() - t
    return PoseResult(t_fine, m.name, v, fitness, rmse, seconds)


def pose_errors(t_est, t_gt, model_points=None):
    """Rotation error (deg), translation error (m) and, with model points, ADD-S (mean
    distance from each estimated model point to the nearest ground-truth one: symmetric
    objects are not penalised for an equivalent pose)."""
    rre, rte = registration.rre_rte(t_est, t_gt)
    if model_points is None:
        return rre, rte
    a = model_points @ t_est[:3, :3].T + t_est[:3, 3]
    b = model_points @ t_gt[:3, :3].T + t_gt[:3, 3]
    return rre, rte, float(np.mean(cKDTree(b).query(a, k=1)[0]))


# ---- the benchmark on labelled frames ----------------------------------------------------------

def colour_classifier(model_frames, seed=0):
    """``classify(points, color_crop) -> instance`` from the HSV histograms of the instances
    in the model frames (logistic regression): the pipeline's 'classify' stage."""
    x, y = [], []
    for fr in model_frames:
        for inst in fr.instances:
            x.append(hsv_histogram(fr.color, fr.mask == inst["id"]))
            y.append(labelled.instance_label(inst))
    model = make_pipeline(StandardScaler(), LogisticRegression(max_iter=5000)).fit(x, y)

    def classify(points, color_crop):
        return model.predict([hsv_histogram(color_crop, color_crop.sum(-1) > 0)])[0]
    return classify


def run(config, workdir, progress=True):
    """Pose benchmark of ``configs/eval_pose.py`` on labelled RGB-D frames: every visible
    instance of every test frame, from its ground-truth box. Writes pose.csv / pose.md."""
    root = config.data.root or synthetic.default_root("objects", config.seed)
    model_frames, test_frames = labelled.split_frames(rgbd.read_object_frames(root),
                                                         config.model_views)
    if config.data.max_frames:
        test_frames = test_frames[:config.data.max_frames]
    views = labelled.build_database(model_frames, 0.03, config.data.voxel / 2)
    models = {}
    for v in views:
        models.setdefault(v.label, ObjectModel(v.label, v.label, []))
        models[v.label].views.append(v.points)
    classify = colour_classifier(model_frames, config.seed)
    rows = []
    for method in [m.strip() for m in config.methods.split(",")]:
        per = []
        for fr in tqdm(test_frames, desc=f"pose {method}", disable=not progress):
            for inst in fr.instances:
                label = labelled.instance_label(inst)
                if label not in models:
                    continue
                masked = np.where((fr.mask == inst["id"])[..., None], fr.color, 0)
                depth = np.where(fr.mask == inst["id"], fr.depth, 0) if config.use_mask \
                    else fr.depth
                res = estimate_pose(depth, fr.intrinsics, inst["box"], list(models.values()),
                                    config.data.voxel, classify, masked, method,
                                    seed=config.seed)
                t_gt = labelled.object_to_camera(fr, inst)
                model_pts = np.concatenate(models[label].views)[::5]
                rre, rte, adds = pose_errors(res.transform, t_gt, model_pts)
                extent = np.linalg.norm(model_pts.max(0) - model_pts.min(0))
                per.append({"correct_model": res.model == label, "rre_deg": rre, "rte_m": rte,
                            "add_s_m": adds, "success": adds < 0.1 * extent,
                            "fitness": res.fitness, "rmse_m": res.rmse, **res.seconds})
        mean = lambda k: float(np.mean([p[k] for p in per])) if per else float("nan")
        stages = ("crop", "classify", "fpfh", "global", "icp")
        total = sum(mean(s) for s in stages)
        rows.append({"method": method, "objects": len(per), "model_accuracy": mean(
            "correct_model"), "success": mean("success"),
                     "add_s_m": float(np.median([p["add_s_m"] for p in per])),
                     "rre_deg": float(np.median([p["rre_deg"] for p in per])),
                     "fitness": mean("fitness"), "rmse_m": mean("rmse_m"),
                     **{f"{s}_s": mean(s) for s in stages}, "total_s": total,
                     "fps": 1.0 / total if total > 0 else float("nan")})
    columns = tuple(rows[0])
    md = f"# Pose pipeline ({len(test_frames)} test frames)\n\n{report.table(rows, columns)}\n"
    report.write(workdir, "pose", rows, columns, md)
    return rows, md


TASK = tasks.Task(run=run, methods=lambda: METHODS)
