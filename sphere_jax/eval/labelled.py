"""Labelled RGB-D frames as the recognition and pose pipelines use them: instance labels and
poses, the split into model and test frames, the database of model views and boxes."""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import cKDTree
from sklearn.neighbors import KDTree

from sphere_jax.data import patches
from sphere_jax.data.readers.rgbd import ObjectFrame
from sphere_jax.data.poses import transform
from sphere_jax.registration.fragments import Fragment, estimate_normals


def project_box(points_cam, intrinsics, margin=0):
    """Pixel box ``[u0, v0, u1, v1]`` of camera-frame points (in front of the camera)."""
    p = np.asarray(points_cam, np.float64)
    p = p[p[:, 2] > 0]
    k = np.asarray(intrinsics, np.float64)
    u = k[0, 0] * p[:, 0] / p[:, 2] + k[0, 2]
    v = k[1, 1] * p[:, 1] / p[:, 2] + k[1, 2]
    return [u.min() - margin, v.min() - margin, u.max() + margin, v.max() + margin]


def unit_rows(desc_KxD):
    """Descriptors scaled to unit length, so one distance threshold serves every method (the
    hand-crafted ones already are; learned ones are not). An undescribed keypoint's NaN row
    becomes zeros: at distance 1 from every unit descriptor, beyond the match thresholds."""
    d = np.nan_to_num(np.asarray(desc_KxD, np.float32), nan=0.0)
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return d / np.where(n > 0, n, 1.0)


@dataclasses.dataclass
class ModelView:
    label: str                      # instance
    category: str
    points: np.ndarray              # object frame
    fragment: Fragment
    descriptors: np.ndarray = None
    tree: cKDTree = None            # over the descriptors, built once for every test frame

    def set_descriptors(self, desc_KxD):
        self.descriptors = unit_rows(desc_KxD)
        self.tree = cKDTree(self.descriptors)


def instance_label(inst):
    """Instances are identified across frames by category and placement (the same object in
    the same scene keeps its pose)."""
    return f"{inst['category']}@{np.round(np.asarray(inst['pose'])[:3, 3], 3).tolist()}"


def object_to_camera(frame: ObjectFrame, inst):
    """The instance's pose in the frame's camera, its scale removed (labels hold rotation ×
    scale)."""
    obj = np.array(inst["pose"], np.float64)
    obj[:3, :3] /= np.linalg.norm(obj[:3, :3], axis=0, keepdims=True)
    return np.linalg.inv(frame.pose) @ obj


def make_fragment(points, leaf, voxel, normal_k=17, viewpoint=(0, 0, 0), key=None):
    pts = patches.voxel_downsample(points, voxel)
    return Fragment(key, pts, estimate_normals(pts, normal_k, viewpoint),
                    patches.uniform_keypoints(pts, leaf), KDTree(pts))


def build_database(frames: list[ObjectFrame], leaf, voxel, min_points=200):
    """One model view per labelled instance of each model frame, in the object's frame."""
    views = []
    for fr in frames:
        pts, px = fr.points()
        ids = fr.mask[px[:, 0], px[:, 1]]
        for inst in fr.instances:
            sel = ids == inst["id"]
            if sel.sum() < min_points:
                continue
            cam_to_obj = np.linalg.inv(object_to_camera(fr, inst))
            p = transform(pts[sel], cam_to_obj).astype(np.float32)
            frag = make_fragment(p, leaf, voxel, viewpoint=cam_to_obj[:3, 3],
                                 key=(fr.name, inst["id"]))
            views.append(ModelView(instance_label(inst), inst["category"], p, frag))
    return views


def split_frames(frames: list[ObjectFrame], model_views_per_scene=2):
    """The first views of every scene build the database, the rest are test frames."""
    scenes = {}
    for fr in frames:
        key = tuple(sorted(instance_label(i) for i in fr.instances))
        # Frames of one scene share their objects' poses; group by any shared instance.
        home = next((k for k in scenes if set(k) & set(key)), key)
        scenes.setdefault(home, []).append(fr)
    model, test = [], []
    for group in scenes.values():
        model += group[:model_views_per_scene]
        test += group[model_views_per_scene:]
    return model, test
