"""Seeded augmentations of point clouds and patches (pure numpy; pass a Generator).

``occlude`` is the seed's occlusion augmentation (CONVENTIONS.md §7, thesis 3.1.5), applied to the
rotated copy only during Compass training; ``rotated_copies`` makes Compass's training pairs
from it.
"""
from __future__ import annotations

import numpy as np
from sklearn.neighbors import NearestNeighbors

from sphere_jax import checks


def random_rotations(rng: np.random.Generator, n=None):
    """Rotations uniform on SO(3) (QR of a Gaussian with the sign fix), ``[3, 3]`` or
    ``[n, 3, 3]``, float64."""
    g = rng.standard_normal(((1 if n is None else n), 3, 3))
    q, r = np.linalg.qr(g)
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    q[:, :, 0] *= np.linalg.det(q)[:, None]
    return q[0] if n is None else q


def rotate(points, rot_33):
    """``p' = R p`` for points ``[..., N, 3]``."""
    return np.asarray(points) @ np.asarray(rot_33).T


def occlude(patch_Nx3, radius, rng: np.random.Generator, p_none=0.5, p_outer=0.8,
            fraction=(0.05, 0.20)):
    """The seed's occlusion: with probability ``p_none`` nothing; otherwise split the patch into
    3 shells by ``⌊3r/R⌋``, choose the outer shell (p = ``p_outer``) or the middle one, pick a
    random point there and delete its k nearest neighbours, k a uniform ``fraction`` of the
    points. Returns the kept points (fewer rows; resample to a fixed N after)."""
    patch = np.asarray(patch_Nx3)
    if len(patch) == 0 or rng.random() < p_none:
        return patch
    shell = np.minimum(np.floor(3 * np.linalg.norm(patch, axis=1) / radius), 2).astype(int)
    target = 2 if rng.random() < p_outer else 1
    candidates = np.nonzero(shell == target)[0]
    if len(candidates) == 0:
        return patch
    centre = patch[rng.choice(candidates)]
    k = int(round(rng.uniform(*fraction) * len(patch)))
    if k == 0:
        return patch
    _, idx = NearestNeighbors(n_neighbors=k).fit(patch).kneighbors(centre[None])
    keep = np.ones(len(patch), bool)
    keep[idx[0]] = False
    return patch[keep]


def resample(points_Mx3, n, rng: np.random.Generator):
    """``n`` rows drawn with replacement (to restore a fixed patch size)."""
    points = np.asarray(points_Mx3)
    if len(points) == 0:
        raise ValueError("resample needs at least one point")
    return points[rng.integers(0, len(points), n)]


def jitter(points, sigma, rng: np.random.Generator, clip=None):
    """Add isotropic Gaussian noise of std ``sigma`` (clipped to ±``clip`` if given)."""
    noise = rng.normal(0.0, sigma, np.shape(points))
    if clip is not None:
        noise = np.clip(noise, -clip, clip)
    return (np.asarray(points) + noise).astype(np.asarray(points).dtype)


def change_density(points, keep_fraction, rng: np.random.Generator):
    """Keep a random ``keep_fraction`` of the points (a sparser scan)."""
    points = np.asarray(points)
    if not 0 < keep_fraction <= 1:
        raise ValueError(f"keep_fraction must be in (0, 1], got {keep_fraction}")
    n = max(1, int(round(keep_fraction * len(points))))
    return points[np.sort(rng.choice(len(points), n, replace=False))]


def rotated_copies(patches_BxNx3, rng: np.random.Generator, occlusion=True, noise=0.0,
                   turns_Bx3x3=None):
    """Each unit patch rotated by a random rotation, occluded (seed 3.1.5), resampled to N
    points and, with ``noise`` > 0, moved by Gaussian noise of that std (units of the radius):
    ``{'copies': [B, N, 3], 'rotations': [B, 3, 3]}`` — Compass's training pairs. With
    ``turns_Bx3x3`` the patches are already turned by those rotations from the frame the
    network's other input is in (copies from another scan), and ``'rotations'`` include them."""
    if not np.isfinite(noise) or noise < 0:
        raise checks.InputError("copy_jitter", "a finite number >= 0", repr(noise))
    b, n, _ = patches_BxNx3.shape
    rots = random_rotations(rng, b)
    cop = np.empty_like(patches_BxNx3)
    for k in range(b):
        rotated = rotate(patches_BxNx3[k], rots[k])
        if occlusion:
            rotated = occlude(rotated, 1.0, rng)
        cop[k] = resample(rotated, n, rng)
        if noise:
            cop[k] = jitter(cop[k], noise, rng)
    if turns_Bx3x3 is not None:
        rots = rots @ turns_Bx3x3
    return {"copies": cop, "rotations": rots.astype(np.float32)}
