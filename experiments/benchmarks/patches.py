"""Patches suite, on a 3DMatch fragment — the real one (:mod:`sphere_jax.paths`) when present,
else a synthetic fragment:

- timing: 5000 patches of 1225 points (radius 0.3 m) from the fragment voxelised at 2 cm
  (keypoint selection and extraction), then their spherical signals;
- memory: the supports of K keypoints on the **full-resolution** fragment drawn as the
  inference API does (:class:`sphere_jax.data.supports.SupportStream`, chunks of 256 patches of 1024
  points streamed, one prepared ahead) against all at once (what extraction did before),
  each K in a fresh process, peak RSS from the kernel; and the whole ``describe`` call of the
  shipped LEAD at the largest K (``--keypoints``).
"""
from __future__ import annotations

import multiprocessing
import os
import resource
import statistics
import time

import numpy as np

from experiments.benchmarks import common

RADIUS, N_POINTS, CHUNK = 0.3, 1024, 256
ALL_AT_ONCE_MAX = 5000        # beyond it the materialised supports outgrow this machine


def _fragment():
    from sphere_jax import paths
    from sphere_jax.data.generators import synthetic
    from sphere_jax.data.readers import io
    shared = paths.real_data("3dmatch", "demo_fullres", "cloud_bin_0.ply")
    if shared and os.path.isfile(shared):
        return "3DMatch demo cloud_bin_0 (../shared/data)", io.read_ply(shared).points
    scene_dir = os.path.join(synthetic.default_root("3dmatch"), "synth-room-0")
    return ("synthetic synth-room-0 cloud_bin_0",
            io.read_ply(os.path.join(scene_dir, "cloud_bin_0.ply")).points)


def run(repeats=5, keypoints=5000, **_):
    records = [_timing(repeats)]
    ks = sorted({k for k in (1000, 5000, 20000, 50000) if k < keypoints} | {keypoints})
    ctx = multiprocessing.get_context("spawn")
    for mode in ("streamed", "all at once", "LEAD describe"):
        for k in ks:
            if mode == "all at once" and k > ALL_AT_ONCE_MAX or \
                    mode == "LEAD describe" and k != ks[-1]:
                continue
            with ctx.Pool(1) as pool:
                rss_mb, seconds, n_points = pool.apply(_memory_child, (k, mode))
            records.append({"source": "memory", "points": n_points, "keypoints": k,
                            "mode": mode, "peak_rss_mb": round(rss_mb), "seconds":
                            round(seconds, 1)})
    return records


def _memory_child(k, mode):
    """In a fresh process: peak RSS (MB) and seconds of drawing K supports."""
    from sphere_jax import parallel
    from sphere_jax.bundles import inference
    from sphere_jax.data import patches, supports
    _, points = _fragment()
    rng = np.random.default_rng(0)
    kp = np.sort(rng.choice(len(points), k, replace=k > len(points)))
    t0 = time.perf_counter()
    if mode == "LEAD describe":                           # the whole API call, shipped LEAD
        inference.load_bundle("lead").describe(points, kp, on_invalid="mask")
    elif mode == "streamed":
        stream = supports.SupportStream(points, kp, RADIUS, N_POINTS, 0, supports.MIN_SUPPORT)
        # A stand-in network: the first point of each patch (the supports are what is measured).
        parallel.stream_chunked(lambda p: p[:, 0], stream.make, stream.n, CHUNK, workers=2)
    else:
        patches.extract_patches(points, kp, RADIUS, N_POINTS, rng)
    seconds = time.perf_counter() - t0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, seconds, len(points)


def _timing(repeats):
    import jax.numpy as jnp
    from sphere_jax.data import patches
    from sphere_jax.spherical import signal
    source, points = _fragment()
    t0 = time.perf_counter()
    down = patches.voxel_downsample(points, 0.02)
    voxel_ms = 1e3 * (time.perf_counter() - t0)
    times, out = [], None
    for seed in range(repeats):
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        kp = patches.random_keypoints(down, 5000, rng)
        out = patches.extract_patches(down, kp, RADIUS, 1225, rng, min_points=300)
        times.append(time.perf_counter() - t0)
    batch = jnp.asarray(out.points[:512])
    signal.patch_signals(batch, RADIUS, 24).block_until_ready()
    sig_ms = common.median_ms(lambda: signal.patch_signals(batch, RADIUS, 24), repeats)
    return {"source": source, "points": len(points), "voxel_2cm_points": len(down),
            "voxel_ms": round(voxel_ms, 1), "patches": len(out.keypoints),
            "extract_ms": round(1e3 * statistics.median(times), 1),
            "signals_512_B24_ms": round(sig_ms, 1)}
