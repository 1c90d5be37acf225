"""Rigid transforms from correspondences: Kabsch on known ones, open3d's RANSAC on putative
matches, point-to-plane ICP to refine. Every transform ``T`` maps the source onto the target,
``p_dst = T · p_src`` (4×4)."""
from __future__ import annotations

import numpy as np

from sphere_jax.data import o3d_convert
from sphere_jax.registration.matching import mutual_matches
from sphere_jax.spherical import so3


def kabsch(src, dst):
    """Rigid ``T`` minimising ``‖T src − dst‖`` (rows correspond)."""
    cs, cd = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1, 1, d]) @ u.T
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = r, cd - r @ cs
    return t


def ransac(points_dst_Mx3, points_src_Mx3, max_distance=0.05, iterations=50_000, seed=0):
    """Rigid ``T̂`` with ``dst ≈ T̂ src`` from putative correspondences (row m of each), by
    open3d's RANSAC with its edge-length and distance pre-checks. Identity if < 3 matches."""
    import open3d as o3d
    if len(points_dst_Mx3) < 3:
        return np.eye(4)
    o3d.utility.random.seed(int(seed))
    src, dst = o3d_convert.point_cloud(points_src_Mx3), o3d_convert.point_cloud(points_dst_Mx3)
    corres = o3d.utility.Vector2iVector(np.repeat(np.arange(len(points_src_Mx3)), 2)
                                        .reshape(-1, 2).astype(np.int32))
    reg = o3d.pipelines.registration
    result = reg.registration_ransac_based_on_correspondence(
        src, dst, corres, max_distance, reg.TransformationEstimationPointToPoint(False), 3,
        [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
         reg.CorrespondenceCheckerBasedOnDistance(max_distance)],
        reg.RANSACConvergenceCriteria(int(iterations), 0.999))
    return np.asarray(result.transformation)


# RANSAC that only ranks a vote's candidate frames (vote.VotedFrames): about 20 ms a
# candidate against 0.2-3 s for the benchmark's 50 000 iterations, and a wrong frame's few
# inliers are told from a right one's many long before that.
SCREEN_ITERATIONS = 5000


def ransac_consensus(points_dst_Mx3, points_src_Mx3, max_distance=0.05, iterations=50_000,
                     seed=0):
    """``(T̂, inliers)``: :func:`ransac`'s transform and how many correspondences it brings
    within ``max_distance``."""
    t = ransac(points_dst_Mx3, points_src_Mx3, max_distance, iterations, seed)
    moved = np.asarray(points_src_Mx3) @ t[:3, :3].T + t[:3, 3]
    return t, int(np.sum(np.linalg.norm(moved - points_dst_Mx3, axis=1) < max_distance))


def rival_consensus(points_dst_Mx3, points_src_Mx3, t, max_distance=0.05, same_deg=15.0,
                    same_distance=0.3, iterations=50_000, seed=0, rounds=3):
    """RANSAC's consensus for a transform other than ``t``: among the correspondences ``t``
    leaves unexplained (farther than twice ``max_distance`` under it), the most one transform
    brings within ``max_distance`` — skipping, up to ``rounds`` times, a consensus whose
    transform is ``t`` again (within ``same_deg`` and ``same_distance``: matches just outside
    the band, which agree with ``t``).

    A transform found by chance among many wrong matches stands barely above its rival, which
    is the chance level of those matches; a right one stands well above it. The ratio needs no
    overlap and grows with neither the number of matches nor the descriptor, which is why
    :mod:`sphere_jax.align` decides ``registered`` by it."""
    dst, src = np.asarray(points_dst_Mx3), np.asarray(points_src_Mx3)
    gap = lambda tr: np.linalg.norm(src @ tr[:3, :3].T + tr[:3, 3] - dst, axis=1)
    left = gap(t) >= 2 * max_distance
    for k in range(rounds):
        if left.sum() < 3:
            return 0
        other, count = ransac_consensus(dst[left], src[left], max_distance, iterations,
                                        seed + k)
        if (np.degrees(so3.geodesic_distance_np(other[:3, :3], t[:3, :3])) >= same_deg
                or np.linalg.norm(other[:3, 3] - t[:3, 3]) >= same_distance):
            return count
        left &= gap(other) >= max_distance
    return 0


def consensus(frag_i, frag_j, desc_i, desc_j, max_distance=0.05, iterations=50_000, seed=0):
    """How many mutual matches of two descriptor sets one rigid transform explains (RANSAC's
    inliers): a pair's agreement measured without its ground truth."""
    ia, ib = mutual_matches(desc_i, desc_j)
    return ransac_consensus(frag_i.points[frag_i.keypoints[ia]],
                            frag_j.points[frag_j.keypoints[ib]], max_distance, iterations,
                            seed)[1]


def point_to_plane_icp(src, dst, t_init, distance, iterations=30):
    """open3d's point-to-plane ICP of two fragments (with the target's normals), at most
    ``iterations`` steps; ``(T, fitness, rmse)``."""
    import open3d as o3d
    reg = o3d.pipelines.registration
    s, d = o3d_convert.point_cloud(src.points), o3d_convert.point_cloud(dst.points, dst.normals)
    out = reg.registration_icp(s, d, distance, np.asarray(t_init, np.float64),
                               reg.TransformationEstimationPointToPlane(),
                               reg.ICPConvergenceCriteria(max_iteration=int(iterations)))
    return np.asarray(out.transformation), float(out.fitness), float(out.inlier_rmse)
