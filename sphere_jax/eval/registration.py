"""Descriptor matching and LRF repeatability on fragment pairs (DESIGN.md §3, thesis 3.2, 4.3).

* Feature-match recall: keypoints of each fragment, mutual nearest neighbours in descriptor
  space; a match is correct if ``‖p_i − T·p_j‖ < τ1`` (0.10 m); a pair is matched if more than
  ``τ2`` (5 %) of its matches are correct; recall per scene.
* LRF repeatability ("perfect detector"): keypoints of fragment i that have a point of j
  within ``match_dist`` after the ground truth; the frame at i and the ground-truth-rotated frame
  at that point of j are repeatable if both x̂ and ẑ agree to a dot product ≥ ρ (0.97).
"""
from __future__ import annotations

import numpy as np
from sklearn.neighbors import NearestNeighbors

from sphere_jax.data import patches


def _transform(points, t):
    return points @ t[:3, :3].T + t[:3, 3]


def mutual_matches(desc_a, desc_b):
    """Indices ``(ia, ib)`` of mutual nearest neighbours (Euclidean) between two sets."""
    ab = NearestNeighbors(n_neighbors=1).fit(desc_b).kneighbors(desc_a)[1][:, 0]
    ba = NearestNeighbors(n_neighbors=1).fit(desc_a).kneighbors(desc_b)[1][:, 0]
    ia = np.nonzero(ba[ab] == np.arange(len(desc_a)))[0]
    return ia, ab[ia]


def load_fragments(scene, voxel):
    """Voxel-downsampled points of every fragment (read once, shared by the evaluations)."""
    return {k: patches.voxel_downsample(scene.cloud(k).points, voxel) for k in scene.fragments}


def _keypoints(points, k, n_keypoints, seed):
    return patches.random_keypoints(points, n_keypoints, np.random.default_rng([seed, k]))


def feature_match_recall(describe, scene, fragments, n_keypoints=5000, tau1=0.10, tau2=0.05,
                         seed=0):
    """``describe(points, keypoint_indices) -> [K, D]``; ``fragments`` from
    :func:`load_fragments`. Returns per-pair rows and the scene's recall."""
    kps = {k: _keypoints(p, k, n_keypoints, seed) for k, p in fragments.items()}
    desc = {k: describe(fragments[k], kps[k]) for k in scene.fragments}
    rows = []
    for i, j in scene.pairs:
        ia, ib = mutual_matches(desc[i], desc[j])
        err = np.linalg.norm(fragments[i][kps[i][ia]]
                             - _transform(fragments[j][kps[j][ib]], scene.transforms[(i, j)]),
                             axis=1)
        ratio = float(np.mean(err < tau1)) if len(err) else 0.0
        rows.append({"pair": (i, j), "matches": int(len(ia)), "inlier_ratio": ratio,
                     "matched": ratio > tau2})
    recall = float(np.mean([r["matched"] for r in rows])) if rows else float("nan")
    return rows, recall


def lrf_repeatability(orient, scene, fragments, n_keypoints=1000, match_dist=0.02, rho=0.97,
                      seed=0):
    """``orient(points, keypoint_indices) -> [K, 3, 3]``; ``fragments`` from
    :func:`load_fragments`. Mean repeatability over pairs."""
    reps = []
    for i, j in scene.pairs:
        pi, pj = fragments[i], fragments[j]
        ki = _keypoints(pi, i, n_keypoints, seed)
        t = scene.transforms[(i, j)]
        pj_in_i = _transform(pj, t)
        dist, idx = NearestNeighbors(n_neighbors=1).fit(pj_in_i).kneighbors(pi[ki])
        keep = dist[:, 0] < match_dist
        if not keep.any():
            continue
        fi = orient(pi, ki[keep])
        fj = t[:3, :3] @ orient(pj, idx[keep, 0])                  # j's frames, in i's frame
        x_ok = np.sum(fi[:, :, 0] * fj[:, :, 0], 1) >= rho
        z_ok = np.sum(fi[:, :, 2] * fj[:, :, 2], 1) >= rho
        reps.append(float(np.mean(x_ok & z_ok)))
    return float(np.mean(reps)) if reps else float("nan")
