"""Keypoints and local patches (numpy; open3d only for ISS).

A patch is what :func:`~sphere_jax.spherical.signal.patch_signal` consumes: N points drawn from
the neighbours within a radius of a keypoint, the keypoint itself excluded, in coordinates
relative to the keypoint. Training draws them independently with replacement (the seed's
augmentation); describing and orienting draw them evenly (:data:`DRAWS`).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks
from sphere_jax.data import o3d_convert


def voxel_downsample(points, voxel, return_index=False):
    """One point per occupied voxel of side ``voxel``: the centroid of the voxel's points
    (``return_index=True``: the index of the point nearest that centroid instead, so
    colours/normals can follow)."""
    points = checks.cloud(points, dtype=None)
    voxel = checks.positive(voxel, "voxel")
    cells = np.floor((points - points.min(0)) / voxel).astype(np.int64)
    keys = np.ravel_multi_index(cells.T, tuple(cells.max(0) + 1))   # one int per voxel: fast
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    centroid = np.stack([np.bincount(inverse, points[:, k], len(counts)) for k in range(3)], 1)
    centroid /= counts[:, None]
    if not return_index:
        return centroid.astype(np.float32)
    dist = np.linalg.norm(points - centroid[inverse], axis=1)
    # Sort by voxel, then by distance to the centroid (one float key: dist/voxel < 1).
    order = np.argsort(inverse + np.minimum(dist / (2 * voxel), 0.999))
    first = np.ones(len(order), bool)
    first[1:] = inverse[order][1:] != inverse[order][:-1]
    return order[first]


def uniform_keypoints(points, leaf):
    """Indices of one keypoint per voxel of side ``leaf`` (the point nearest each voxel's
    centroid): an even spread, e.g. one every 10 cm."""
    return voxel_downsample(points, leaf, return_index=True)


def random_keypoints(points, n, rng: np.random.Generator):
    """``n`` distinct random indices (all of them if the cloud is smaller)."""
    points = checks.cloud(points, dtype=None)
    return np.sort(rng.choice(len(points), size=min(n, len(points)), replace=False))


def iss_keypoints(points, salient_radius=0.0, non_max_radius=0.0, gamma_21=0.975,
                  gamma_32=0.975, min_neighbors=5):
    """Intrinsic Shape Signature keypoints (open3d); radii 0 let open3d pick from resolution.
    Returns indices into ``points``."""
    import open3d as o3d
    points = checks.cloud(points, dtype=None)
    pcd = o3d_convert.point_cloud(points)
    kp = o3d.geometry.keypoint.compute_iss_keypoints(pcd, salient_radius, non_max_radius,
                                                     gamma_21, gamma_32, min_neighbors)
    kp = np.asarray(kp.points)
    if len(kp) == 0:
        return np.zeros(0, np.int64)
    _, idx = KDTree(points).query(kp, k=1)
    return np.unique(idx[:, 0])


@dataclasses.dataclass
class Patches:
    """``points [P, N, 3]`` float32 relative to each keypoint; ``keypoints [P]`` indices into
    the cloud; ``counts [P]`` neighbours each patch was drawn from."""
    points: np.ndarray
    keypoints: np.ndarray
    counts: np.ndarray


def extract_patches(points, keypoints, radius, n_points, rng: np.random.Generator,
                    min_points=1, tree=None) -> Patches:
    """Patches of ``n_points`` drawn with replacement from the neighbours within ``radius`` of
    each keypoint (indices into ``points``), the keypoint excluded. Keypoints with fewer than
    ``min_points`` neighbours are dropped (the seed skips supports under 300 points); the
    result says which were kept."""
    points = checks.cloud(points, dtype=None)
    keypoints, _ = checks.keypoints(np.asarray(keypoints, np.int64).reshape(-1), len(points))
    got = patches_around(points, points[keypoints], radius, n_points, rng, min_points, tree)
    return Patches(got.points[got.valid], keypoints[got.valid], got.counts[got.valid])


@dataclasses.dataclass
class Supports:
    """``points [K, N, 3]`` float32 relative to each centre (zeros where not ``valid``);
    ``counts [K]`` neighbours each was drawn from; ``valid [K]``: ``counts >= min_points``."""
    points: np.ndarray
    counts: np.ndarray
    valid: np.ndarray


# How a patch's N points are drawn from a support of c points. 'random': N independent draws
# with replacement (training's; each point's count is binomial, so two scans of one surface
# give two noisy signals). 'even': N evenly spaced positions in the support's list from one
# random offset, so every point is drawn N // c or N // c + 1 times when c <= N, and N spread
# over the list (the k-d tree's spatial order) when c > N. On the 14 redkitchen 3DMatch pairs
# 'even' lifts LEAD (Compass)'s inlier ratio by 11 % and LEAD (FLARE)'s by 7 %, more than
# 4096 random draws do (docs/evaluation.md, "How supports are drawn"), at no cost.
DRAWS = ("random", "even")


def patches_around(points, centres_Kx3, radius, n_points, rng: np.random.Generator,
                   min_points=1, tree=None, draw="random") -> Supports:
    """Patches of ``n_points`` drawn (``draw``, one of :data:`DRAWS`) from the points of
    ``points`` within ``radius`` of each centre (which need not be a point of the cloud),
    points at the centre itself excluded: they give no direction. Random numbers are drawn
    for the valid centres only, in order, so consecutive calls on consecutive chunks equal
    one call on all."""
    radius = checks.positive(radius, "radius")
    n_points = checks.positive(n_points, "n_points", integer=True)
    checks.choice(draw, "draw", DRAWS)
    centres_Kx3 = np.asarray(centres_Kx3, points.dtype).reshape(-1, 3)   # compared exactly
    tree = KDTree(points) if tree is None else tree
    neigh = tree.query_radius(centres_Kx3, radius) if len(centres_Kx3) else []
    flat = np.concatenate(neigh).astype(np.int64) if len(neigh) else np.zeros(0, np.int64)
    owner = np.repeat(np.arange(len(centres_Kx3)), [len(n) for n in neigh])
    keep = np.any(points[flat] != centres_Kx3[owner], axis=1)
    flat, owner = flat[keep], owner[keep]
    counts = np.bincount(owner, minlength=len(centres_Kx3))
    valid = counts >= max(min_points, 1)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    kept = np.nonzero(valid)[0]
    if draw == "random":
        position = rng.random((len(kept), n_points))
    else:
        position = (np.arange(n_points) + rng.random((len(kept), 1))) / n_points
    pick = starts[kept, None] + np.minimum(np.floor(position * counts[kept, None]),
                                           counts[kept, None] - 1).astype(np.int64)
    out = np.zeros((len(centres_Kx3), n_points, 3), np.float32)
    out[kept] = points[flat[pick]] - centres_Kx3[kept][:, None, :]
    return Supports(out, counts, valid)


def unit_shapes(shapes_BxNx3):
    """Whole shapes as unit patches (CONVENTIONS.md §7, ModelNet): centred on the centroid of
    their points, in units of the largest distance from it. Both turn with the shape (a
    bounding box does not: a turned shape would be re-centred and re-scaled), so a rotated
    shape gives exactly the rotated patch. Returns ``(patches, centres [B, 1, 3])``."""
    shapes = np.asarray(shapes_BxNx3, np.float64)
    centres = shapes.mean(1, keepdims=True)
    radius = np.linalg.norm(shapes - centres, axis=2).max(1)[:, None, None]
    return ((shapes - centres) / np.maximum(radius, 1e-9)).astype(np.float32), centres
