"""Rigid transforms of scans: points moved by a 4×4 transform, and the poses of 3DMatch-layout
training scans from their ground truth, for Compass's cross-scan copies
(``data.copy_draw='scan'``).

A scene folder of ``cloud_bin_K.ply`` with a ``gt.log`` (``p_i = T_ij p_j``, beside the clouds or
in ``<scene>-evaluation/``) gives each fragment joined to the scene's first one by ground-truth
pairs a pose in that fragment's frame, breadth first; scans of other folders (fused RGB-D
sequences, single files) get none and train on same-scan copies.
"""
from __future__ import annotations

import collections
import os
import re

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax.data.readers import threedmatch

_FRAGMENT = re.compile(r"cloud_bin_(\d+)\.ply")


def transform(points, t):
    """``points [N, 3]`` mapped by the 4×4 rigid transform ``t``."""
    return points @ t[:3, :3].T + t[:3, 3]


def overlap(points_i, points_j, t_ij, voxel) -> float:
    """Share of ``points_j`` (both on a ``voxel`` grid), moved by ``t_ij`` into i's frame, within
    2 voxels of ``points_i``: a pair's overlap under its ground truth."""
    d, _ = KDTree(points_i).query(transform(points_j, t_ij), k=1)
    return float(np.mean(d[:, 0] < 2 * voxel))


def relative(poses_Sx4x4, s, t):
    """The 4×4 transform taking scan ``s``'s points into scan ``t``'s frame."""
    return np.linalg.inv(poses_Sx4x4[t]) @ poses_Sx4x4[s]


def _gt_log(folder):
    for d in (folder + "-evaluation", folder):
        if os.path.isfile(os.path.join(d, "gt.log")):
            return os.path.join(d, "gt.log")
    return None


def scene_poses(scan_paths):
    """``(scene [S] int, poses [S, 4, 4] float64)`` for the scans ``scan_paths``: scans of one
    scene share a scene number and ``poses[s]`` maps scan s into the scene's frame; scene -1
    (pose NaN) where no ground truth reaches the scan."""
    scene = np.full(len(scan_paths), -1, np.int64)
    poses = np.full((len(scan_paths), 4, 4), np.nan)
    by_folder = collections.defaultdict(dict)
    for s, path in enumerate(scan_paths):
        m = _FRAGMENT.fullmatch(os.path.basename(str(path)))
        if m:
            by_folder[os.path.dirname(os.path.abspath(str(path)))][int(m.group(1))] = s
    for number, (folder, index) in enumerate(sorted(by_folder.items())):
        log = _gt_log(folder)
        if log is None:
            continue
        transforms, _ = threedmatch.read_gt_log(log)
        edges = collections.defaultdict(list)
        for (i, j), t in transforms.items():
            if i in index and j in index:
                edges[i].append((j, t))                  # P_j = P_i T_ij
                edges[j].append((i, np.linalg.inv(t)))
        root = min(index)
        pose = {root: np.eye(4)}
        queue = collections.deque([root])
        while queue:
            i = queue.popleft()
            for j, t in edges[i]:
                if j not in pose:
                    pose[j] = pose[i] @ t
                    queue.append(j)
        for k, p in pose.items():
            scene[index[k]], poses[index[k]] = number, p
    return scene, poses
