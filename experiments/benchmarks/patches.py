"""Patches suite: 5000 patches of 1225 points (radius 0.3 m) from a 3DMatch fragment voxelised
at 2 cm — the real one (:mod:`sphere_jax.paths`) when present, else a synthetic fragment —
timing keypoint selection and patch extraction, then the spherical signals."""
from __future__ import annotations

import os
import statistics
import time

import jax.numpy as jnp
import numpy as np

from experiments.benchmarks import common
from sphere_jax import paths
from sphere_jax.data import patches
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import io
from sphere_jax.spherical import signal


def run(repeats=5, **_):
    shared = paths.real_data("3dmatch", "demo_fullres", "cloud_bin_0.ply")
    if shared and os.path.isfile(shared):
        source, points = "3DMatch demo cloud_bin_0 (../shared/data)", io.read_ply(shared).points
    else:
        scene_dir = os.path.join(synthetic.ensure_default_data(), "3dmatch", "synth-room-0")
        source = "synthetic synth-room-0 cloud_bin_0"
        points = io.read_ply(os.path.join(scene_dir, "cloud_bin_0.ply")).points
    t0 = time.perf_counter()
    down = patches.voxel_downsample(points, 0.02)
    voxel_ms = 1e3 * (time.perf_counter() - t0)
    times, out = [], None
    for seed in range(repeats):
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        kp = patches.random_keypoints(down, 5000, rng)
        out = patches.extract_patches(down, kp, 0.3, 1225, rng, min_points=300)
        times.append(time.perf_counter() - t0)
    batch = jnp.asarray(out.points[:512])
    signal.patch_signals(batch, 0.3, 24).block_until_ready()
    sig_ms = common.median_ms(lambda: signal.patch_signals(batch, 0.3, 24), repeats)
    return [{"source": source, "points": len(points), "voxel_2cm_points": len(down),
             "voxel_ms": round(voxel_ms, 1), "patches": len(out.keypoints),
             "extract_ms": round(1e3 * statistics.median(times), 1),
             "signals_512_B24_ms": round(sig_ms, 1)}]
