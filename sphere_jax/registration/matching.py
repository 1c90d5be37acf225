"""Mutual nearest neighbours between two descriptor sets, in blocks of a distance matrix."""
from __future__ import annotations

import numpy as np


def mutual_matches(desc_a_KxD, desc_b_KxD):
    """Indices ``(ia, ib)`` of mutual nearest neighbours (Euclidean) between two sets. A row
    that is not finite (a keypoint left undescribed: NaN) takes no part. A zero row would: at
    distance 1 from every unit-length descriptor it becomes the nearest neighbour of all
    those farther apart, and silently drops their matches."""
    desc_a_KxD, desc_b_KxD = np.asarray(desc_a_KxD), np.asarray(desc_b_KxD)
    if desc_a_KxD.ndim != 2 or desc_b_KxD.ndim != 2 or \
            desc_a_KxD.shape[1] != desc_b_KxD.shape[1]:
        raise ValueError(f"descriptors must be [K, D] with the same D, got {desc_a_KxD.shape} "
                         f"and {desc_b_KxD.shape}")
    rows_a = np.flatnonzero(np.isfinite(desc_a_KxD).all(1))
    rows_b = np.flatnonzero(np.isfinite(desc_b_KxD).all(1))
    if len(rows_a) == 0 or len(rows_b) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    a, b = desc_a_KxD[rows_a], desc_b_KxD[rows_b]
    ab = nearest(a, b)
    ba = nearest(b, a)
    ia = np.nonzero(ba[ab] == np.arange(len(a)))[0]
    return rows_a[ia], rows_b[ab[ia]]


def nearest(query_QxD, base_BxD, rows=256):
    """Index in ``base`` of each query's nearest neighbour (Euclidean), by blocks of ``rows``
    queries: the largest ``q·b − ‖b‖²/2`` (= −(‖q − b‖² − ‖q‖²)/2, the same order and ties
    as the distance, exactly: halving is exact in float64), one float64 matmul per block,
    scored in place. A KD-tree degenerates to a slow brute force in hundreds of dimensions
    (5000 × 5000 at D = 512: 3 s against 0.2 s). Blocks of 256 rows keep the scores (10 MB
    for 5000 bases) near the cache: 1024 made matching 1.5–4× slower on 2 cores."""
    q, b = np.asarray(query_QxD, np.float64), np.asarray(base_BxD, np.float64)
    half_sq = 0.5 * np.einsum("bd,bd->b", b, b)
    out = np.empty(len(q), np.int64)
    for s in range(0, len(q), rows):
        score = q[s:s + rows] @ b.T
        score -= half_sq
        out[s:s + rows] = np.argmax(score, axis=1)
    return out
