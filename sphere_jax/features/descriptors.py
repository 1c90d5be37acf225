"""Hand-crafted local descriptors on exact neighbourhoods: SHOT, Spin Images (numpy), FPFH (open3d).

All take a prepared cloud (points, unit normals turned towards the sensor) and keypoint indices,
and return float32 ``[K, D]`` rows of unit length (zero rows where a keypoint has no
neighbours), so they can be matched like the learned descriptors.

* SHOT (Tombari et al. 2010), 352 values: in the SHOT LRF, 32 volumes (8 azimuth × 2 elevation
  × 2 radial sectors) each holding an 11-bin histogram of ``cos`` between the neighbour's normal
  and the LRF's ẑ; every neighbour votes with quadrilinear interpolation (histogram bin,
  azimuth, elevation, radius), then the whole vector is normalised.
* Spin image (Johnson & Hebert 1999), 153 values: about the keypoint normal n, each neighbour
  at offset d maps to ``(α, β) = (‖d − (d·n) n‖, d·n)``, accumulated bilinearly into a
  (W+1) × (2W+1) grid over ``α ∈ [0, R], β ∈ [−R, R]`` (W = 8, as PCL's default).
* USC, Unique Shape Context (Tombari, Salti & Di Stefano 2010), 1960 values: Frome's 3-D shape
  context in the SHOT LRF — 10 radial shells spaced logarithmically from R/10 to R (the
  nearer neighbours fall in the first), 14 elevation bins of equal angle from ẑ, 14 azimuth bins
  from x̂; each neighbour adds ``1 / (ρ · V^(1/3))``, ρ the number of points within R/5 of it
  (itself included) and V its bin's volume, as PCL's ``UniqueShapeContext``; the frame being
  unique, no azimuthal copies are kept.
* FPFH (Rusu et al. 2009), 33 values: open3d's implementation.
"""
from __future__ import annotations

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax.data import o3d_convert
from sphere_jax.features.lrfs import shot_lrf
from sphere_jax.features.neighbourhood import Neighbourhoods

SHOT_BINS, SHOT_AZIMUTH, SHOT_ELEVATION, SHOT_RADIAL = 11, 8, 2, 2
SHOT_DIM = SHOT_BINS * SHOT_AZIMUTH * SHOT_ELEVATION * SHOT_RADIAL
SPIN_WIDTH = 8
USC_RADIAL, USC_ELEVATION, USC_AZIMUTH = 10, 14, 14
USC_DIM = USC_RADIAL * USC_ELEVATION * USC_AZIMUTH
USC_MIN_RADIUS, USC_DENSITY_RADIUS = 0.1, 0.2       # fractions of the support radius


def usc_shells(radius, bins=USC_RADIAL, min_fraction=USC_MIN_RADIUS):
    """The ``bins + 1`` shell radii, logarithmically spaced from ``min_fraction · R`` to R."""
    return radius * np.exp(np.log(min_fraction) * (1.0 - np.arange(bins + 1) / bins))


def usc_volumes(radius):
    """``[radial, elevation]`` volumes of USC's bins (equal for every azimuth)."""
    r = usc_shells(radius)
    theta = np.linspace(0.0, np.pi, USC_ELEVATION + 1)
    dr = (r[1:] ** 3 - r[:-1] ** 3) / 3.0
    dcos = np.cos(theta[:-1]) - np.cos(theta[1:])
    return dr[:, None] * dcos[None, :] * (2 * np.pi / USC_AZIMUTH)


def _normalise(desc_KxD):
    norm = np.linalg.norm(desc_KxD, axis=1, keepdims=True)
    return (desc_KxD / np.where(norm > 0, norm, 1.0)).astype(np.float32)


def _linear(u, n, cyclic=False):
    """Interpolation of a continuous bin coordinate ``u`` (bin centres at integers) onto
    ``n`` bins: the two bins ``(lo, hi)`` and their weights ``(1 − f, f)``; at the ends of a
    non-cyclic axis both votes land in the edge bin."""
    lo = np.floor(u)
    f = u - lo
    lo = lo.astype(np.int64)
    hi = lo + 1
    if cyclic:
        return (lo % n, hi % n), (1.0 - f, f)
    return (np.clip(lo, 0, n - 1), np.clip(hi, 0, n - 1)), (1.0 - f, f)


def shot(nb: Neighbourhoods, normals_Nx3, frames_Kx3x3=None):
    """SHOT descriptors ``[K, 352]`` of the keypoints of ``nb`` (frames: SHOT LRFs by default)."""
    frames = shot_lrf(nb) if frames_Kx3x3 is None else np.asarray(frames_Kx3x3, np.float64)
    valid = np.all(np.isfinite(frames), axis=(1, 2))
    frames = np.where(valid[:, None, None], frames, np.eye(3))
    f = frames[nb.owner]                                       # [M, 3, 3]
    q = np.einsum("mi,mij->mj", nb.local, f)                  # neighbour in the LRF
    cos = np.clip(np.einsum("mi,mi->m", normals_Nx3[nb.index].astype(np.float64), f[:, :, 2]),
                  -1.0, 1.0)
    r = nb.radius
    azimuth = np.arctan2(q[:, 1], q[:, 0])                     # (−π, π]
    elevation = np.arctan2(q[:, 2], np.hypot(q[:, 0], q[:, 1]))   # [−π/2, π/2]
    axes = [
        _linear((1.0 + cos) / 2.0 * SHOT_BINS - 0.5, SHOT_BINS),
        _linear((azimuth + np.pi) / (2 * np.pi) * SHOT_AZIMUTH - 0.5, SHOT_AZIMUTH, cyclic=True),
        _linear((elevation + np.pi / 2) / np.pi * SHOT_ELEVATION - 0.5, SHOT_ELEVATION),
        _linear(nb.dist / r * SHOT_RADIAL - 0.5, SHOT_RADIAL),
    ]
    strides = [1, SHOT_BINS, SHOT_BINS * SHOT_AZIMUTH, SHOT_BINS * SHOT_AZIMUTH * SHOT_ELEVATION]
    hist = np.zeros(nb.n_keypoints * SHOT_DIM)
    base = nb.owner * SHOT_DIM
    for corner in range(16):                                  # 2⁴ interpolation corners
        index, weight = base, np.ones(len(base))
        for k, ((lo, hi), (w_lo, w_hi)) in enumerate(axes):
            up = (corner >> k) & 1
            index = index + strides[k] * (hi if up else lo)
            weight = weight * (w_hi if up else w_lo)
        hist += np.bincount(index, weight, minlength=len(hist))
    out = hist.reshape(nb.n_keypoints, SHOT_DIM)
    out[~valid] = 0.0
    return _normalise(out)


def spin_image(nb: Neighbourhoods, keypoint_normals_Kx3, width=SPIN_WIDTH):
    """Spin images ``[K, (W+1)(2W+1)]`` about the keypoints' normals."""
    n = np.asarray(keypoint_normals_Kx3, np.float64)[nb.owner]
    beta = np.einsum("mi,mi->m", nb.local, n)
    alpha = np.sqrt(np.maximum(nb.dist ** 2 - beta ** 2, 0.0))
    scale = width / nb.radius
    cols, rows = width + 1, 2 * width + 1
    (a0, a1), (wa0, wa1) = _linear(alpha * scale, cols)
    (b0, b1), (wb0, wb1) = _linear(beta * scale + width, rows)
    base = nb.owner * (rows * cols)
    hist = np.zeros(nb.n_keypoints * rows * cols)
    for a, wa in ((a0, wa0), (a1, wa1)):
        for b, wb in ((b0, wb0), (b1, wb1)):
            hist += np.bincount(base + b * cols + a, wa * wb, minlength=len(hist))
    return _normalise(hist.reshape(nb.n_keypoints, rows * cols))


def usc(nb: Neighbourhoods, points_Nx3, frames_Kx3x3=None, tree=None):
    """USC descriptors ``[K, 1960]`` of the keypoints of ``nb`` (frames: SHOT LRFs by default);
    the local densities are counted in ``points`` (``tree``: its sklearn KD-tree, if built)."""
    frames = shot_lrf(nb) if frames_Kx3x3 is None else np.asarray(frames_Kx3x3, np.float64)
    valid = np.all(np.isfinite(frames), axis=(1, 2))
    frames = np.where(valid[:, None, None], frames, np.eye(3))
    q = np.einsum("mi,mij->mj", nb.local, frames[nb.owner])   # neighbour in the LRF
    r = nb.radius
    shell = np.clip(np.searchsorted(usc_shells(r)[1:], nb.dist, side="left"), 0, USC_RADIAL - 1)
    theta = np.arccos(np.clip(q[:, 2] / nb.dist, -1.0, 1.0))
    elev = np.clip((theta / np.pi * USC_ELEVATION).astype(np.int64), 0, USC_ELEVATION - 1)
    phi = np.mod(np.arctan2(q[:, 1], q[:, 0]), 2 * np.pi)
    azim = np.clip((phi / (2 * np.pi) * USC_AZIMUTH).astype(np.int64), 0, USC_AZIMUTH - 1)
    unique, inverse = np.unique(nb.index, return_inverse=True)
    points_Nx3 = np.asarray(points_Nx3, np.float64)
    tree = KDTree(points_Nx3) if tree is None else tree
    density = tree.query_radius(points_Nx3[unique], USC_DENSITY_RADIUS * r,
                                count_only=True)[inverse.reshape(-1)]
    w = 1.0 / (np.maximum(density, 1) * np.cbrt(usc_volumes(r)[shell, elev]))
    bins = (azim * USC_ELEVATION + elev) * USC_RADIAL + shell
    hist = np.bincount(nb.owner * USC_DIM + bins, w, minlength=nb.n_keypoints * USC_DIM)
    out = hist.reshape(nb.n_keypoints, USC_DIM)
    out[~valid] = 0.0
    return _normalise(out)


def fpfh(points_Nx3, normals_Nx3, keypoints_K, radius, max_nn=100):
    """FPFH ``[K, 33]`` from open3d (its neighbourhood search: ``radius``, at most ``max_nn``)."""
    import open3d as o3d
    pcd = o3d_convert.point_cloud(points_Nx3, normals_Nx3)
    param = o3d.geometry.KDTreeSearchParamHybrid(radius=float(radius), max_nn=int(max_nn))
    keypoints_K = np.asarray(keypoints_K, np.int64)
    # open3d returns the features of the sorted, de-duplicated indices: map back to the order
    # asked for.
    unique, inverse = np.unique(keypoints_K, return_inverse=True)
    try:                                                      # open3d >= 0.19: keypoints only
        feat = o3d.pipelines.registration.compute_fpfh_feature(pcd, param, unique.tolist())
        data = np.asarray(feat.data).T
    except TypeError:
        data = np.asarray(o3d.pipelines.registration.compute_fpfh_feature(pcd, param).data).T
        data = data[unique]
    return _normalise(data[inverse.reshape(-1)])
