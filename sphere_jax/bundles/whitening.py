"""Descriptor whitening: a linear map fitted once on a bundle's training scans, stored in it.

A learned descriptor's dimensions vary on very different scales: LEAD's 512 values are a
band-limited SO(3) map (84 spectral degrees of freedom at B = 4) whose principal variances span
five orders of magnitude, so plain Euclidean nearest neighbours are decided by the few
directions that vary most. Whitening — centre, turn to the principal axes, scale each to unit
variance, turn back — and then unit length makes matching weigh every direction by how much it
varies across training keypoints (a Mahalanobis distance). Directions with no variance (the
descriptor's null space) are dropped; ``EPS`` · λ_max is added to every variance so that
near-null directions are not blown up. Nothing about it is learned from labels.

The statistics depend on the frames a descriptor is turned to, so a bundle keeps one whitening
per frame source: ``default`` (the kind's own frames: FLARE for LEAD and LEAD-PN, its own for
SOUND) and, for LEAD, ``compass`` (fitted with a Compass bundle's frames).

Files in the bundle: ``whitening.npz`` (``{source}.mean`` ``[D]``, ``{source}.axes``
``[D, k]``, ``{source}.scales`` ``[k]``, float32) and ``whitening.json`` (how each was fitted).
"""
from __future__ import annotations

import dataclasses
import io as bytes_io
import json
import os

import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax import checks, files
from sphere_jax.bundles import store
from sphere_jax.spherical import so3, transforms

FILE = store.WHITENING
STATEMENT = "whitening.json"
SOURCES = ("default", "compass")
EPS = 1e-5              # of the largest variance; 1e-6 .. 1e-4 gave LEAD 0.249 .. 0.262 IR
NULL = 1e-9             # variances below NULL · λ_max are the descriptor's null space


@dataclasses.dataclass(frozen=True)
class Whitening:
    """``apply(desc) = unit(((desc · weights − mean) · axes / scales) · axesᵀ)``: the whitened
    descriptor in the original coordinates (same width D), of unit length. ``weights`` (None:
    all 1) scale the coordinates first: :func:`rotation_averaged` works in coordinates where
    turning an SO(3) map is an orthogonal map."""
    mean: np.ndarray            # [D]
    axes: np.ndarray            # [D, k] principal axes, orthonormal columns
    scales: np.ndarray          # [k] sqrt(variance + EPS · λ_max)
    weights: np.ndarray | None = None   # [D]

    def transform(self, desc_KxD):
        """``[K, D]`` float64: whitened, before unit length (Euclidean distances between
        these are Mahalanobis distances under the fitted covariance)."""
        x = np.asarray(desc_KxD, np.float64)
        if x.ndim != 2 or x.shape[1] != len(self.mean):
            raise checks.InputError("descriptors", f"[K, {len(self.mean)}] (the width the "
                                    "whitening was fitted on)", checks.shown(x))
        if self.weights is not None:
            x = x * self.weights
        return ((x - self.mean) @ self.axes / self.scales) @ self.axes.T

    def apply(self, desc_KxD):
        """``[K, D]`` whitened descriptors of unit length, float32; a NaN row (an undescribed
        keypoint) stays NaN."""
        y = self.transform(desc_KxD)
        norm = np.linalg.norm(y, axis=1, keepdims=True)
        return (y / np.maximum(norm, 1e-12)).astype(np.float32)


def fit(desc_NxD, eps=EPS) -> Whitening:
    """The whitening of descriptors ``[N, D]`` (N > D rows, all finite), in float64."""
    x = np.asarray(desc_NxD, np.float64)
    if x.ndim != 2 or len(x) <= x.shape[1] or not np.isfinite(x).all():
        raise checks.InputError("desc_NxD", "finite descriptors [N, D] with N > D",
                                checks.shown(x))
    mean = x.mean(0)
    return _of_moments(mean, np.cov((x - mean).T), eps)


def _of_moments(mean_D, cov_DxD, eps=EPS, weights_D=None) -> Whitening:
    variances, axes = np.linalg.eigh(cov_DxD)
    variances, axes = variances[::-1], axes[:, ::-1]
    keep = variances > NULL * variances[0]
    return Whitening(mean_D, axes[:, keep], np.sqrt(variances[keep] + eps * variances[0]),
                     weights_D)


# maps [K, 2B, 2B, 2B] and rotations [Q, 3, 3] -> every map turned by every rotation
_turn_each = jax.jit(jax.vmap(transforms.rotate_so3, (None, 0)))


def rotation_averaged(w: Whitening, bandwidth: int, eps=EPS) -> Whitening:
    """The whitening of the same descriptors turned to uniformly random frames, for SO(3)
    maps ``[(2B)³]`` (LEAD's) at ``bandwidth`` B: what matching in a frame shared by a whole
    scan needs (the pair vote's second pass), where no keypoint's map is in a canonical pose.

    The fitted covariance C (of ``w``, its regularised variances ``scales²``) and mean μ are
    averaged over SO(3), ``E_Q[T_Q (C + μμᵀ) T_Qᵀ] − μ̄μ̄ᵀ``, exactly: the integrand has degree
    < 2B, which the SOFT quadrature over the B grid's rotations integrates exactly. It works
    in Haar-weighted coordinates (each grid value times √(Haar weight)), where T_Q is
    orthogonal, so the averaged covariance commutes with every turn and the whitening is
    equivariant: turning all maps by one rotation leaves their whitened distances unchanged
    (``tests/bundles/test_whitening.py``)."""
    side = 2 * bandwidth
    if w.weights is not None or len(w.mean) != side ** 3:
        raise checks.InputError("w", f"a plain whitening of [{side ** 3}] SO(3) maps at B = "
                                f"{bandwidth}", f"one of width {len(w.mean)}")
    haar = np.broadcast_to(so3.haar_weights(bandwidth)[:, None, None], (side,) * 3)
    root = np.sqrt(haar).ravel()
    columns = np.concatenate([w.axes * w.scales, w.mean[:, None]], 1).T      # [k + 1, D]
    maps = jnp.asarray(columns.reshape((-1,) + (side,) * 3), jnp.float32)
    rotations = jnp.asarray(so3.so3_grid_matrices(bandwidth).reshape(-1, 3, 3), jnp.float32)
    turned = np.asarray(_turn_each(maps, rotations), np.float64)       # [Q, k + 1, 2B, 2B, 2B]
    turned = turned.reshape(len(rotations), len(columns), -1) * root
    quad = haar.ravel()                                      # Σ = 1 over the grid's rotations
    rows = (turned * np.sqrt(quad)[:, None, None]).reshape(-1, len(root))
    second = rows.T @ rows                                   # one GEMM: Σ_q quad_q Σ_k v vᵀ
    mean = quad @ turned[:, -1]
    cov = second - np.outer(mean, mean)
    return _of_moments(mean, (cov + cov.T) / 2, eps, root)


def save(bundle_dir, whitenings: dict, statement: dict):
    """Write ``whitenings`` (source -> :class:`Whitening`) and how they were fitted into the
    bundle folder, atomically; sources already there and not given are kept."""
    unknown = set(whitenings) - set(SOURCES)
    if unknown:
        raise checks.InputError("whitenings", f"sources among {SOURCES}", sorted(unknown))
    kept = load(bundle_dir)
    kept.update(whitenings)
    arrays = {f"{s}.{f.name}": np.asarray(getattr(w, f.name), np.float32)
              for s, w in kept.items() for f in dataclasses.fields(w)
              if getattr(w, f.name) is not None}
    buffer = bytes_io.BytesIO()
    np.savez(buffer, **arrays)
    files.atomic_write(os.path.join(bundle_dir, FILE), buffer.getvalue())
    old = read_statement(bundle_dir)
    old.update(statement)
    files.atomic_write(os.path.join(bundle_dir, STATEMENT), json.dumps(old, indent=1))


def load(bundle_dir) -> dict:
    """``{source: Whitening}`` of a bundle folder (empty when it has none). A bundle whose
    ``whitening.json`` states fitted whitenings but whose ``whitening.npz`` is missing (a
    partial copy, an install without the package data) is a :class:`BundleError`, never a
    silent fall-back to raw descriptors."""
    path = os.path.join(str(bundle_dir), FILE)
    if not os.path.isfile(path):
        stated = read_statement(bundle_dir)
        if stated:
            raise checks.BundleError(bundle_dir, f"its {STATEMENT} states the whitening of "
                                     f"{', '.join(sorted(stated))} but {FILE} is missing")
        return {}
    try:
        with np.load(path) as z:
            arrays = {k: z[k].astype(np.float64) for k in z.files}
    except Exception as e:
        raise checks.BundleError(bundle_dir, f"its {FILE} does not read ({e})") from None
    sources = sorted({k.split(".")[0] for k in arrays})
    try:
        return {s: Whitening(arrays[f"{s}.mean"], arrays[f"{s}.axes"], arrays[f"{s}.scales"],
                             arrays.get(f"{s}.weights")) for s in sources}
    except KeyError as e:
        raise checks.BundleError(bundle_dir, f"its {FILE} lacks {e}") from None


def read_statement(bundle_dir) -> dict:
    """``whitening.json``: per source, the scans, keypoints and frames it was fitted on."""
    return store.read_json(bundle_dir, STATEMENT)
