"""A spinning LiDAR over a dense scan: another sensor's sampling of the same geometry.

A rotating multi-beam LiDAR (Velodyne-like) returns, for each of ``beams`` fixed elevations and
each azimuth step, the nearest surface along that ray, with range noise. Over a point cloud the
ray cast is approximated by the nearest point whose direction lies within the beam's angular
footprint (``footprint`` degrees either side): the return is put on the ray itself, so the
resampled scan has the sensor's rings, its density falling with range, and none of the source's
grid. Used to make registration pairs of a sensor the shipped bundles never saw (the redkitchen
fragments as seen by a LiDAR at their camera) for :mod:`sphere_jax.training.adaptation`.
"""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from sphere_jax import checks, files, workdirs
from sphere_jax.data.readers import io, ply, threedmatch


@dataclasses.dataclass(frozen=True)
class Lidar:
    beams: int = 32
    elevation: tuple[float, float] = (-25.0, 25.0)   # degrees, lowest and highest beam
    azimuth_step: float = 0.2                        # degrees between firings
    footprint: float = 0.3                           # degrees either side of a ray
    range_noise: float = 0.01                        # σ of the range error, in the cloud's unit

    def __post_init__(self):
        checks.positive(self.beams, "beams", integer=True)
        checks.positive(self.azimuth_step, "azimuth_step")
        checks.positive(self.footprint, "footprint")
        checks.non_negative(self.range_noise, "range_noise")
        low, high = self.elevation
        if not -90 < low <= high < 90:
            raise checks.InputError("elevation", "(lowest, highest) degrees within (-90, 90)",
                                    self.elevation)

    def elevations(self):
        """``[beams]`` beam elevations in radians, lowest first."""
        return np.deg2rad(np.linspace(*self.elevation, self.beams))


def sensor_frame(up, forward=None):
    """``[3, 3]`` rows: the sensor's x (``forward`` made orthogonal to ``up``; None: the
    cloud's z axis, or its x axis when ``up`` is z), y and z (up) axes in the cloud's frame."""
    z = np.asarray(up, float)
    z = z / checks.positive(float(np.linalg.norm(z)), "up (its length)")
    if forward is None:
        forward = (1.0, 0.0, 0.0) if abs(z[2]) > 0.9 else (0.0, 0.0, 1.0)
    x = np.asarray(forward, float) - np.dot(forward, z) * z
    if np.linalg.norm(x) < 1e-6:
        raise checks.InputError("forward", "a direction not parallel to up", forward)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def scan(points, lidar: Lidar = Lidar(), origin=(0.0, 0.0, 0.0), up=(0.0, -1.0, 0.0),
         rng: np.random.Generator | None = None) -> np.ndarray:
    """The returns ``[M, 3]`` (float32, the cloud's frame) of ``lidar`` at ``origin`` spinning
    about ``up`` over ``points [N, 3]``. The default ``up`` is a camera frame's (y down), so a
    3DMatch fragment is scanned from its first camera. ``rng``: range noise (none without)."""
    points = checks.cloud(points, "points", np.float64)
    frame = sensor_frame(up)
    local = (points - np.asarray(origin, float)) @ frame.T
    r = np.linalg.norm(local, axis=1)
    keep = r > 1e-9
    local, r = local[keep], r[keep]
    elev = np.arcsin(np.clip(local[:, 2] / r, -1.0, 1.0))
    azim = np.arctan2(local[:, 1], local[:, 0])
    step, half = np.deg2rad(lidar.azimuth_step), np.deg2rad(lidar.footprint)
    n_az = int(round(2 * np.pi / step))
    rays_el, rays_az, ranges = [], [], []
    for e in lidar.elevations():
        hit = np.abs(elev - e) <= half
        if not hit.any():
            continue
        # Every azimuth bin within the footprint of a point sees it; the nearest wins.
        lo = np.floor((azim[hit] - half) / step).astype(np.int64)
        span = int(np.ceil(2 * half / step)) + 1
        bins = (lo[:, None] + np.arange(span)) % n_az
        centre = (bins + 0.5) * step
        d_az = np.angle(np.exp(1j * (centre - azim[hit][:, None])))
        ok = np.abs(d_az) <= half
        b, rr = bins[ok], np.broadcast_to(r[hit][:, None], bins.shape)[ok]
        best = np.full(n_az, np.inf)
        np.minimum.at(best, b, rr)
        fired = np.flatnonzero(np.isfinite(best))
        rays_el.append(np.full(len(fired), e))
        rays_az.append((fired + 0.5) * step)
        ranges.append(best[fired])
    if not ranges:
        return np.zeros((0, 3), np.float32)
    e, a, rng_m = (np.concatenate(v) for v in (rays_el, rays_az, ranges))
    if rng is not None:
        rng_m = rng_m + rng.normal(0.0, lidar.range_noise, rng_m.shape)
    rays = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], 1)
    return (rays * rng_m[:, None] @ frame + np.asarray(origin, float)).astype(np.float32)


def scan_fragments(fragment_dir, out_dir, lidar: Lidar = Lidar(), seed=0):
    """Each ``cloud_bin_K.ply`` of a 3DMatch scene folder scanned by ``lidar`` from the
    fragment's first camera, written to ``out_dir/<scene>/cloud_bin_K.ply``, with the sensor
    in ``lidar.json``. No ground truth is copied: evaluations take the source's
    (``--config.data.gt``), adaptation has none to read. Returns ``{fragment: returns}``."""
    fragment_dir = os.path.normpath(str(fragment_dir))
    ks = threedmatch.fragment_indices(fragment_dir)
    if not ks:
        raise checks.MissingError(f"{fragment_dir}: no cloud_bin_K.ply fragments to scan")
    out = workdirs.prepare(os.path.join(str(out_dir), os.path.basename(fragment_dir)),
                           "out_dir")
    counts = {}
    for k in ks:
        rng = np.random.default_rng([seed, k])
        cloud = io.read_points(os.path.join(fragment_dir, f"cloud_bin_{k}.ply")).points
        returns = scan(cloud, lidar, rng=rng)
        ply.write_ply(os.path.join(out, f"cloud_bin_{k}.ply"), returns)
        counts[k] = len(returns)
    files.atomic_write(os.path.join(out, "lidar.json"), json.dumps(dict(
        source=fragment_dir, seed=seed, returns=counts, **dataclasses.asdict(lidar)),
        indent=1).encode())
    return counts
