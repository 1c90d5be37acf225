"""Real fragments for the evaluation tests (../shared/data), prepared as the benchmark does."""
from __future__ import annotations

import os

import numpy as np

from sphere_jax.data.readers import threedmatch
from sphere_jax.eval import scenes


def kitchen(shared) -> scenes.PairSet:
    root = os.path.join(shared, "3dmatch", "7-scenes-redkitchen")
    return scenes.fragment_scene(threedmatch.load_fragment_scene(root, root + "-evaluation"))


def bunny(shared, voxel=0.001) -> scenes.PairSet:
    return scenes.stanford_scans(os.path.join(shared, "stanford", "bunny", "data", "bun.conf"),
                                 voxel)


def rotated_copy(frag: scenes.Fragment, rot_33) -> scenes.Fragment:
    """The same fragment turned about the origin (normals turned with it, keypoints kept)."""
    from sklearn.neighbors import KDTree
    pts = (frag.points @ rot_33.T).astype(np.float32)
    return scenes.Fragment(frag.key, pts, (frag.normals @ rot_33.T).astype(np.float32),
                           frag.keypoints, KDTree(pts))
