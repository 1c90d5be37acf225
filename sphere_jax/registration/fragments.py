"""A scan prepared for matching: voxelised points, normals turned towards the sensor, keypoints
and a KD-tree (CONVENTIONS.md §7: 2 cm voxel, normals from 17 neighbours, 5000 keypoints at
3DMatch's scale)."""
from __future__ import annotations

import dataclasses

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks
from sphere_jax.data import o3d_convert, patches


@dataclasses.dataclass
class Fragment:
    """A prepared scan: ``points [N, 3]`` float32, unit ``normals [N, 3]``, ``keypoints [K]``
    indices into ``points``; ``tree`` a KD-tree over ``points``."""
    key: object
    points: np.ndarray
    normals: np.ndarray
    keypoints: np.ndarray
    tree: KDTree


def estimate_normals(points, k=17, viewpoint=(0.0, 0.0, 0.0)):
    """Unit normals ``[N, 3]`` from the PCA of each point's ``k`` nearest neighbours (open3d),
    turned towards ``viewpoint`` — the sensor, which is the origin of a 3DMatch fragment (the
    fragment frame is its first camera's); rotating a fragment about the origin keeps it so."""
    import open3d as o3d
    points = checks.cloud(points, dtype=None)
    pcd = o3d_convert.point_cloud(points)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(int(k)))
    pcd.orient_normals_towards_camera_location(np.asarray(viewpoint, np.float64))
    return np.asarray(pcd.normals, np.float32)


def fragment(key, points_Nx3, voxel, rng: np.random.Generator, n_keypoints=5000, normal_k=17,
             viewpoint=(0.0, 0.0, 0.0), given_keypoints=None) -> Fragment:
    """Voxelise ``points_Nx3``, estimate normals, pick keypoints: ``given_keypoints`` (snapped
    to the nearest voxelised point) or ``n_keypoints`` random points drawn with ``rng``."""
    points = patches.voxel_downsample(points_Nx3, voxel)
    normals = estimate_normals(points, normal_k, viewpoint)
    tree = KDTree(points)
    if given_keypoints is not None:
        keypoints = tree.query(np.asarray(given_keypoints, np.float64), k=1)[1][:, 0]
    else:
        keypoints = patches.random_keypoints(points, n_keypoints, rng)
    return Fragment(key, points, normals, keypoints, tree)
