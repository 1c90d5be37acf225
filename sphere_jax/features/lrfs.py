"""Hand-crafted local reference frames on exact neighbourhoods (vectorised numpy).

Frames are ``[K, 3, 3]`` with columns x̂, ŷ, ẑ in world coordinates (the convention of
:mod:`sphere_jax.models.flare`, whose JAX FLARE the learned pipelines use on resampled patches).

* SHOT (Tombari, Salti & Di Stefano 2010): eigenvectors of the covariance about the keypoint,
  each neighbour weighted by ``R − d``; x̂ largest, ẑ smallest eigenvalue; each sign chosen so
  that most neighbours lie on its positive side (the sum of projections breaks ties).
* TOLDI (Yang, Zhang, Xiao & Cao 2017): ẑ is the normal of the neighbours within R/3 (PCA about
  their centroid), turned so the neighbours lie below it (Σ dᵢ·ẑ ≤ 0); x̂ is the sum of the
  neighbours' projections on the tangent plane weighted by ``((R − dᵢ)·(dᵢ·ẑ))²``.
* 3DSN (Gojcic, Zhou, Wegner & Wieser 2019, 3DSmoothNet's variant of TOLDI): ẑ is the
  eigenvector of the smallest eigenvalue of the scatter of *all* neighbours about the keypoint
  itself (TOLDI: the neighbours within R/3, about their centroid), turned the same way; x̂ as
  TOLDI's.
* GFrames (Melzi et al. 2019): ẑ the normal (TOLDI's), x̂ the tangent gradient of a scalar
  field over the support. On a mesh the paper differentiates an intrinsic field (mean
  curvature, an eigenfunction); on points we take the **normal deviation**
  ``f = 1 − |nᵢ·ẑ|`` of each neighbour's own normal from the keypoint's: it needs only the
  normals every fragment has, is invariant to rotation and to the normals' signs, and grows
  where the surface bends away from the keypoint's tangent plane — a curvature proxy whose
  gradient points from the flat part of the support towards where it bends most. The gradient
  is a weighted least-squares plane ``f ≈ a + g·t`` over the neighbours' tangent coordinates
  ``t`` (weights ``R − d``); on a plane or a sphere, where ``f`` has no direction, x̂ is
  arbitrary, as every LRF's is there.

Keypoints with too few neighbours get NaN frames; callers count them as not repeatable.
"""
from __future__ import annotations

import numpy as np

from sphere_jax.features.neighbourhood import Neighbourhoods


def _outer_sum(nb: Neighbourhoods, vectors_Mx3, weights_M):
    outer = (weights_M[:, None, None] * vectors_Mx3[:, :, None]) * vectors_Mx3[:, None, :]
    return nb.sum(outer)


def _disambiguate(nb: Neighbourhoods, axes_Kx3):
    """Flip each axis so that the majority of its keypoint's neighbours project positively."""
    proj = np.sum(nb.local * axes_Kx3[nb.owner], axis=1)
    votes = nb.sum(np.sign(proj)) + 1e-9 * np.sign(nb.sum(proj))
    return np.where((votes < 0)[:, None], -axes_Kx3, axes_Kx3)


def _frames(x_Kx3, z_Kx3, valid_K):
    y = np.cross(z_Kx3, x_Kx3)
    y /= np.maximum(np.linalg.norm(y, axis=1, keepdims=True), 1e-12)
    x = np.cross(y, z_Kx3)                                    # exactly orthogonal to ẑ
    frames = np.stack([x, y, z_Kx3], axis=2)
    frames[~valid_K] = np.nan
    return frames


def shot_lrf(nb: Neighbourhoods, min_neighbours=5):
    """SHOT's LRF for every keypoint of ``nb`` -> ``[K, 3, 3]``."""
    w = np.maximum(nb.radius - nb.dist, 0.0)
    cov = _outer_sum(nb, nb.local, w) / np.maximum(nb.sum(w), 1e-12)[:, None, None]
    _, vecs = np.linalg.eigh(cov)                              # ascending eigenvalues
    x = _disambiguate(nb, vecs[:, :, 2])
    z = _disambiguate(nb, vecs[:, :, 0])
    return _frames(x, z, nb.counts >= min_neighbours)


def toldi_lrf(nb: Neighbourhoods, min_neighbours=5):
    """TOLDI's LRF for every keypoint of ``nb`` -> ``[K, 3, 3]``."""
    z, n_inner = _inner_normal(nb)
    return _toldi_x(nb, z, (nb.counts >= min_neighbours) & (n_inner >= 3))


def _inner_normal(nb: Neighbourhoods):
    """TOLDI's normal: the PCA normal of the neighbours within R/3, about their centroid
    (either sign), ``[K, 3]``, and how many neighbours it had ``[K]``."""
    inner = nb.within(nb.radius / 3.0)
    centroid = inner.sum(inner.local) / np.maximum(inner.counts, 1)[:, None]
    centred = inner.local - centroid[inner.owner]
    _, vecs = np.linalg.eigh(_outer_sum(inner, centred, np.ones(len(centred))))
    return vecs[:, :, 0], inner.counts


def _below(nb: Neighbourhoods, z_Kx3):
    """ẑ turned so the neighbours lie below it (Σ dᵢ·ẑ ≤ 0)."""
    return np.where((np.sum(nb.sum(nb.local) * z_Kx3, axis=1) > 0)[:, None], -z_Kx3, z_Kx3)


def threedsn_lrf(nb: Neighbourhoods, min_neighbours=5):
    """3DSmoothNet's LRF for every keypoint of ``nb`` -> ``[K, 3, 3]``."""
    _, vecs = np.linalg.eigh(_outer_sum(nb, nb.local, np.ones(len(nb.local))))
    return _toldi_x(nb, vecs[:, :, 0], nb.counts >= min_neighbours)


def _toldi_x(nb: Neighbourhoods, z_Kx3, valid_K):
    """ẑ turned so the neighbours lie below it, and TOLDI's x̂: the tangent projections
    weighted by ``((R − dᵢ)·(dᵢ·ẑ))²``."""
    z = _below(nb, z_Kx3)
    height = np.sum(nb.local * z[nb.owner], axis=1)
    tangent = nb.local - height[:, None] * z[nb.owner]
    w = ((nb.radius - nb.dist) * height) ** 2
    x = nb.sum(w[:, None] * tangent)
    x /= np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-12)
    return _frames(x, z, valid_K)


def gframes_lrf(nb: Neighbourhoods, normals_Nx3, min_neighbours=5):
    """GFrames' LRF for every keypoint of ``nb`` -> ``[K, 3, 3]``; ``normals_Nx3``: the cloud's
    normals (any sign), indexed by ``nb.index``."""
    z, n_inner = _inner_normal(nb)
    z = _below(nb, z)
    # Any orthonormal tangent basis (e1, e2): the fitted gradient does not depend on it.
    e1 = np.cross(z, np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(z, e1)
    field = 1.0 - np.abs(np.sum(np.asarray(normals_Nx3, np.float64)[nb.index] * z[nb.owner],
                                axis=1))
    design = np.stack([np.ones(len(nb.local)), np.sum(nb.local * e1[nb.owner], axis=1),
                       np.sum(nb.local * e2[nb.owner], axis=1)], axis=1)     # [M, 3]
    w = np.maximum(nb.radius - nb.dist, 0.0)
    normal_eq = _outer_sum(nb, design, w) + 1e-12 * np.eye(3)
    rhs = nb.sum((w * field)[:, None] * design)
    coef = np.linalg.solve(normal_eq, rhs[:, :, None])[:, :, 0]
    x = coef[:, 1:2] * e1 + coef[:, 2:3] * e2
    x /= np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-12)
    return _frames(x, z, (nb.counts >= min_neighbours) & (n_inner >= 3))
