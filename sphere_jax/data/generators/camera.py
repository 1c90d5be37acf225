"""A virtual RGB-D camera over open3d's ``RaycastingScene``, with a Kinect-like error model.

Pinhole convention as :func:`sphere_jax.data.readers.rgbd.depth_to_cloud`: x right, y down, z
forward; poses are camera-to-world. Depth error (Khoshelham & Elberink 2012; Nguyen et al.
2012): axial noise σ(z) = 0.0012 + 0.0019 (z - 0.4)² m, disparity quantisation
Δz ≈ z²/350 m, millimetre storage, dropouts at grazing incidence, out of range and at random.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import open3d as o3d


@dataclasses.dataclass(frozen=True)
class Camera:
    width: int = 320
    height: int = 240
    fx: float = 292.5          # 3DMatch's Kinect intrinsics (585 at 640×480), halved
    fy: float = 292.5
    min_depth: float = 0.4
    max_depth: float = 4.5

    @property
    def intrinsics(self):
        return np.array([[self.fx, 0, (self.width - 1) / 2], [0, self.fy, (self.height - 1) / 2],
                         [0, 0, 1.0]])


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """Camera-to-world pose ``[4, 4]`` at ``eye`` looking at ``target`` (image y points down)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, np.cross(z, x), z], 1)
    pose[:3, 3] = eye
    return pose


class Scene:
    """Meshes with an albedo each, ready for ray casting."""

    def __init__(self, meshes, albedos):
        self._rc = o3d.t.geometry.RaycastingScene()
        self.albedos = np.asarray(albedos, np.float32).reshape(-1, 3)
        ids = [self._rc.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
               for m in meshes]
        if ids != list(range(len(meshes))):
            raise RuntimeError(f"unexpected RaycastingScene geometry ids {ids}")

    def render(self, camera: Camera, pose, rng: np.random.Generator | None = None):
        """Render one view: ``depth [H, W]`` float32 metres (0 = no return), ``color [H, W, 3]``
        uint8 (albedo × head-light shading) and ``ids [H, W]`` int32 (-1 = background).
        With ``rng`` the depth carries the sensor error model; without, it is exact."""
        k = camera.intrinsics
        v, u = np.mgrid[0:camera.height, 0:camera.width].astype(np.float64)
        d_cam = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u)], -1)
        d_world = d_cam @ pose[:3, :3].T          # z component 1 in the camera: t_hit = depth
        rays = np.concatenate([np.broadcast_to(pose[:3, 3], d_world.shape), d_world], -1)
        hit = self._rc.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
        depth = hit["t_hit"].numpy().astype(np.float64)
        ids = hit["geometry_ids"].numpy().astype(np.int64)
        missing = ~np.isfinite(depth) | (ids >= len(self.albedos))
        ids = np.where(missing, -1, ids).astype(np.int32)
        depth = np.where(missing, 0.0, depth)
        normals = hit["primitive_normals"].numpy()
        view = d_world / np.linalg.norm(d_world, axis=-1, keepdims=True)
        cos = np.abs(np.sum(normals * view, -1))
        shade = np.where(missing, 0.0, 0.25 + 0.75 * cos)[..., None]
        color = np.clip(self.albedos[np.maximum(ids, 0)] * shade * 255, 0, 255).astype(np.uint8)
        if rng is not None:
            depth = sensor_depth(depth, cos, rng, camera)
        depth = np.where((depth < camera.min_depth) | (depth > camera.max_depth), 0.0, depth)
        return depth.astype(np.float32), color, ids


def sensor_depth(depth, cos_incidence, rng, camera: Camera):
    """Apply the Kinect-like error model to exact depth (0 stays 0)."""
    valid = depth > 0
    z = depth + rng.normal(size=depth.shape) * (0.0012 + 0.0019 * (depth - 0.4) ** 2)
    z = np.where(valid, z, 1.0)
    z = 350.0 / np.maximum(np.round(350.0 / z), 1.0)               # disparity quantisation
    z = np.round(z * 1000.0) / 1000.0                              # millimetre storage
    grazing = rng.random(depth.shape) > np.clip(cos_incidence / 0.2, 0.0, 1.0)
    random_drop = rng.random(depth.shape) < 0.01
    keep = valid & ~grazing & ~random_drop
    return np.where(keep, z, 0.0)
