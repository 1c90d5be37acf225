"""The one place our arrays become open3d objects (open3d wants float64, contiguous, in its own
vector types); open3d is imported lazily so that the package loads without it."""
from __future__ import annotations

import numpy as np


def point_cloud(points_Nx3, normals_Nx3=None):
    """An ``open3d.geometry.PointCloud`` of ``points_Nx3`` (and ``normals_Nx3``), as float64."""
    import open3d as o3d
    vec = lambda a: o3d.utility.Vector3dVector(np.ascontiguousarray(a, np.float64))
    pcd = o3d.geometry.PointCloud(vec(points_Nx3))
    if normals_Nx3 is not None:
        pcd.normals = vec(normals_Nx3)
    return pcd


def feature(desc_KxD):
    """Descriptors as the ``open3d.pipelines.registration.Feature`` (``data`` is ``[D, K]``
    float64) that open3d's feature-matching RANSAC and FGR take."""
    import open3d as o3d
    f = o3d.pipelines.registration.Feature()
    f.data = np.ascontiguousarray(np.asarray(desc_KxD, np.float64).T)
    return f
