"""Exact radius neighbourhoods of keypoints as ragged arrays, and surface normals (numpy/open3d).

Hand-crafted LRFs and descriptors are defined on *every* neighbour within the support radius,
as their papers state, not on the fixed-size resampled patches the networks consume. The
neighbours of all keypoints are concatenated, sorted by keypoint; ``owner[m]`` says whose
neighbour ``m`` is, and per-keypoint sums are one ``np.add.reduceat`` — no Python loop over
keypoints, no padding to the largest neighbourhood.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks


@dataclasses.dataclass
class Neighbourhoods:
    """Neighbours within ``radius`` of ``K`` keypoints (the keypoint itself excluded).

    ``index [M]`` into the cloud, ``owner [M]`` keypoint of each (non-decreasing),
    ``local [M, 3]`` float64 offset from the keypoint, ``dist [M]`` its length,
    ``counts [K]``, ``starts [K]`` first row of each keypoint.
    """
    index: np.ndarray
    owner: np.ndarray
    local: np.ndarray
    dist: np.ndarray
    counts: np.ndarray
    radius: float

    @property
    def n_keypoints(self):
        return len(self.counts)

    @property
    def starts(self):
        return np.concatenate([[0], np.cumsum(self.counts)[:-1]]).astype(np.int64)

    def sum(self, values_M):
        """Per-keypoint sums of ``values [M, ...]`` -> ``[K, ...]`` (0 for empty ones)."""
        values_M = np.asarray(values_M)
        out = np.zeros((self.n_keypoints,) + values_M.shape[1:], values_M.dtype)
        full = self.counts > 0
        if full.any():
            # reduceat over the starts of non-empty segments only: empty ones would return a
            # stray element, and a start equal to M is out of range.
            out[full] = np.add.reduceat(values_M, self.starts[full], axis=0)
        return out

    def within(self, radius):
        """The sub-neighbourhoods within a smaller ``radius`` (e.g. TOLDI's R/3 for ẑ)."""
        keep = self.dist <= radius
        return Neighbourhoods(self.index[keep], self.owner[keep], self.local[keep],
                              self.dist[keep], np.bincount(self.owner[keep],
                                                           minlength=self.n_keypoints),
                              float(radius))


def radius_neighbourhoods(points, keypoints_Kx3, radius, tree=None) -> Neighbourhoods:
    """All points of ``points [N, 3]`` within ``radius`` of each of ``keypoints [K, 3]``."""
    points = checks.cloud(points, dtype=None)
    keypoints_Kx3 = np.asarray(keypoints_Kx3, np.float64).reshape(-1, 3)
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    tree = KDTree(points) if tree is None else tree
    neigh = tree.query_radius(keypoints_Kx3, radius) if len(keypoints_Kx3) else []
    counts = np.array([len(n) for n in neigh], np.int64)
    index = np.concatenate(neigh).astype(np.int64) if len(neigh) else np.zeros(0, np.int64)
    owner = np.repeat(np.arange(len(keypoints_Kx3)), counts)
    local = points[index].astype(np.float64) - keypoints_Kx3[owner]
    dist = np.linalg.norm(local, axis=1)
    keep = dist > 1e-12 * radius                               # no direction from the centre
    return Neighbourhoods(index[keep], owner[keep], local[keep], dist[keep],
                          np.bincount(owner[keep], minlength=len(keypoints_Kx3)), float(radius))


