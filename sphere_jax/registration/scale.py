"""The grid and support a pair of scans is registered at, chosen from the clouds.

The shipped networks were trained on room fragments at 3DMatch's scale, voxelised at 2 cm with
0.3 m supports — 15 voxels, about 700 points on a surface — and a 3DMatch fragment's middle
bounding-box side (2–98 % of its points) is about 2.1 m. :func:`auto_scale` keeps that
proportion (side × 0.02 / 2.1) unless the scan is sparser than that (then its own point
spacing), with supports of 15 voxels, so a support holds as many points as at training time
whatever the unit: a Stanford scan (middle side 0.12 m) gets 1.2 mm voxels and 1.8 cm supports,
close to the seed's 1.5 cm.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sphere_jax import checks

TRAIN_VOXEL, TRAIN_RADIUS = 0.02, 0.30      # the shipped bundles' data.voxel and data.radius
FRAGMENT_SIDE = 2.1                         # middle bounding-box side of a 3DMatch fragment, m


def middle_side(points_Nx3) -> float:
    """The middle side of the box holding 2–98 % of the points on each axis (robust to
    stray points; a room fragment's is its width, a flat scan's its shorter horizontal side)."""
    lo, hi = np.percentile(points_Nx3, 2, axis=0), np.percentile(points_Nx3, 98, axis=0)
    return float(np.sort(hi - lo)[1])


def point_spacing(points_Nx3, samples=5000, seed=0) -> float:
    """Median distance from a point to its nearest other point (sampled queries, full tree)."""
    rng = np.random.default_rng(seed)
    query = points_Nx3[rng.choice(len(points_Nx3), min(samples, len(points_Nx3)), False)]
    d = cKDTree(points_Nx3).query(query, k=2)[0][:, 1]
    d = d[d > 0]
    return float(np.median(d)) if len(d) else 0.0


def auto_scale(*clouds):
    """``(voxel, radius)`` for the clouds (``[N, 3]`` each) of one scene or sensor (module
    docstring): the largest middle side decides, unless a cloud is sparser than that."""
    side = max(middle_side(c) for c in clouds)
    voxel = max([side * TRAIN_VOXEL / FRAGMENT_SIDE] + [point_spacing(c) for c in clouds])
    if not voxel > 0:
        raise checks.InputError("the clouds", "clouds with extent",
                                "clouds whose points coincide")
    return voxel, voxel * TRAIN_RADIUS / TRAIN_VOXEL
