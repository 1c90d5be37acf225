"""Fragments for the evaluation tests, prepared as the benchmark does: the real ones (the
shared scans) where the test needs real data, else an embedded synthetic one."""
from __future__ import annotations

import os

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import paths
from sphere_jax.data import scan_roots
from sphere_jax.data.readers import threedmatch
from sphere_jax.eval import pair_sets
from sphere_jax.registration.fragments import Fragment


def kitchen(shared) -> pair_sets.PairSet:
    root = os.path.join(shared, "3dmatch", "7-scenes-redkitchen")
    return pair_sets.fragment_scene(threedmatch.load_fragment_scene(root, root + "-evaluation"))


def kitchen_or_embedded() -> pair_sets.PairSet:
    """The real redkitchen fragments when present, else the first embedded synthetic room
    (3DMatch layout, 2.5 cm fused depth): what a test runs on when it only needs a real-looking
    scan, so that a fresh clone skips nothing."""
    root = paths.real_data_root()
    if root is not None:
        return kitchen(root)
    return pair_sets.find_pair_sets(scan_roots.default_scan_root())[0]


def bunny(shared, voxel=0.001) -> pair_sets.PairSet:
    return pair_sets.stanford_scans(os.path.join(shared, "stanford", "bunny", "data", "bun.conf"),
                                 voxel)


def rotated_copy(frag: Fragment, rot_33) -> Fragment:
    """The same fragment turned about the origin (normals turned with it, keypoints kept)."""
    pts = (frag.points @ rot_33.T).astype(np.float32)
    return Fragment(frag.key, pts, (frag.normals @ rot_33.T).astype(np.float32),
                           frag.keypoints, KDTree(pts))


def moved_pair(n_keypoints=48):
    """A prepared scan f and g, the same scan moved by T⁻¹ (so p_f = T p_g, as for a benchmark
    pair (f, g)), and T: corresponding keypoints share their index."""
    from sphere_jax.spherical import so3
    pair_set = kitchen_or_embedded()
    f = pair_sets.prepare(pair_set, pair_set.pairs[0][0], n_keypoints=n_keypoints, seed=1)
    t = np.eye(4)
    t[:3, :3] = so3.euler_to_matrix_np(0.9, 1.3, -2.1)
    t[:3, 3] = [0.4, -0.2, 1.0]
    moved = pair_sets.transform(f.points, np.linalg.inv(t)).astype(np.float32)
    g = Fragment(f.key, moved, (f.normals @ t[:3, :3]).astype(np.float32), f.keypoints,
                        KDTree(moved))
    return f, g, t


def relative_difference(a, b):
    """‖a − b‖ / ‖b‖ (Frobenius)."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))
