"""Describe suite: what registering two scans costs a user, per method.

For each method (the evaluation's names: FPFH, SHOT, USC beside the shipped learned ones), in a
fresh process on a real 3DMatch fragment (redkitchen 0; a synthetic room's fragment without the
real scans) at ``--keypoints`` keypoints:

* ``ms_per_keypoint``: the warm description time (the second pass over the keypoints);
* ``gflop_per_keypoint``: XLA's cost analysis of the jitted networks it runs, per patch (the
  hand-crafted methods run no XLA: null), ``gflop_per_s`` what that achieves and
  ``peak_fraction`` its share of this run's float32 matmul rate (both cores);
* ``others_cpu``: the share of the cores other processes used during that pass
  (:mod:`sphere_jax.eval.timing`; above 0.1 the time is not the method's alone);
* ``peak_rss_gb``: the process's peak resident memory;
* ``register_s``: :func:`sphere_jax.register` end to end on one real pair (redkitchen 5 → 0),
  cold (compilation included, as a user's first call), its stages in ``register_stages``
  and the keypoints it described per scan in ``register_described`` (it stops at the first
  share of them that registers with confidence); ``register_warm_s`` the same in a second process
  that finds the first's compiled programs on disk (:mod:`sphere_jax.compile_cache`), as a user's
  next ``experiments.register``.
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

METHODS = ("fpfh", "shot", "usc", "lead", "lead_compass", "lead_modes", "lead_pn", "sound")
# The jitted networks each learned method runs on a patch: (bundle kind, function); the
# spectral turns of lead_modes's maps into its frame hypotheses are not counted.
NETWORKS = {"lead": (("lead", "describe"),), "lead_compass": (("compass", "orient"),
                                                               ("lead", "describe")),
            "lead_modes": (("compass", "orient"), ("lead", "describe")),
            "lead_pn": (("lead_pn", "describe"),), "sound": (("sound", "describe"),)}


def run(keypoints=5000, only=None, **_):
    """One record per method, each measured in its own process."""
    from experiments.benchmarks.layers import matmul_gflops
    peak = matmul_gflops()
    records = []
    for method in METHODS:
        if only and only not in method:
            continue
        with tempfile.TemporaryDirectory(prefix="sphere_jax_bench_xla_") as cache:
            out = _measure_in_process(method, keypoints, cache)
            warm = json.loads(_measure_in_process(method, keypoints, cache, "warm"))
        rec = json.loads(out)
        rec["register_warm_s"] = warm["register_s"]
        gflops = rec.pop("gflop")
        rec["gflop_per_keypoint"] = None if gflops is None else round(gflops, 4)
        rate = None if gflops is None else gflops / (rec["ms_per_keypoint"] * 1e-3)
        rec["gflop_per_s"] = None if rate is None else round(rate, 1)
        rec["peak_fraction"] = None if rate is None else round(rate / peak, 3)
        rec["matmul_gflop_per_s"] = round(peak, 1)
        records.append(rec)
        print(json.dumps(rec), file=sys.stderr, flush=True)      # partial results survive
    return records


def _measure_in_process(method, keypoints, cache, *what):
    """The last stdout line of :func:`measure` (or :func:`register_time`) run in a fresh
    process whose compiled programs go to ``cache``."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run([sys.executable, "-m", "experiments.benchmarks.describe", method,
                          str(keypoints), *what], capture_output=True, text=True, cwd=root,
                         env={**os.environ, "SPHERE_JAX_COMPILE_CACHE": cache})
    if out.returncode != 0:
        raise RuntimeError(f"describe benchmark of {method} failed:\n{out.stderr[-2000:]}")
    return out.stdout.strip().splitlines()[-1]


def _pair():
    """``(scene, i, j)``: the benchmark's pair, redkitchen 0 and 5 (a synthetic room's first
    pair without the real scans); fragment ``i`` is described, ``j`` registered onto it."""
    import glob
    from sphere_jax import paths
    from sphere_jax.data import scan_roots
    from sphere_jax.data.readers import threedmatch
    kitchen = paths.real_data("3dmatch", "7-scenes-redkitchen")
    if kitchen and os.path.isdir(kitchen):
        return threedmatch.load_fragment_scene(kitchen), 0, 5
    first = sorted(glob.glob(os.path.join(scan_roots.default_scan_root(), "*",
                                          "cloud_bin_0.ply")))[0]
    scene = threedmatch.load_fragment_scene(os.path.dirname(first))
    return (scene, *scene.pairs[0])


def pair_files():
    """``(source, target)`` files of the pair to register."""
    scene, i, j = _pair()
    return scene.fragment_path(j), scene.fragment_path(i)


def fragments(keypoints):
    """``(fragment to describe, (source, target) files of the pair to register)``."""
    from sphere_jax.eval import pair_sets
    scene, i, j = _pair()
    with warnings.catch_warnings():          # the pairs of fragments not here: not used
        warnings.simplefilter("ignore")
        frag = pair_sets.prepare(pair_sets.fragment_scene(scene), i, n_keypoints=keypoints)
    return frag, (scene.fragment_path(j), scene.fragment_path(i))


def unrolled_gflop(jitted, *args):
    """XLA's flop count (GFLOP) of the jitted ``jitted`` on ``args``.

    XLA's cost analysis counts a loop's body once, and the networks run a chunk in slices of
    patches (:func:`sphere_jax.parallel.in_slices`), the fused layers loop over cache-sized
    blocks (:func:`sphere_jax.spherical.fused.pointwise`), PointNet and the patch signal over
    patches (``PATCHES_PER_STEP`` of :mod:`sphere_jax.models.pointnet` and
    :mod:`sphere_jax.spherical.signal`): the function is therefore lowered (never run) without
    the slices and with one block for the whole input — the same arithmetic, without loops."""
    import jax
    from unittest import mock
    from sphere_jax.models import pointnet
    from sphere_jax.spherical import fused, signal
    # A new function object: jit would otherwise reuse the trace of the blocked network.
    fn = jitted.__wrapped__
    unrolled = jax.jit(lambda *a, f=getattr(fn, "whole", fn): f(*a))
    with mock.patch.object(fused, "BLOCK_FLOATS", 2 ** 62), \
            mock.patch.object(pointnet, "PATCHES_PER_STEP", 2 ** 62), \
            mock.patch.object(signal, "PATCHES_PER_STEP", 2 ** 62):
        cost = unrolled.lower(*args).compile().cost_analysis()
    cost = cost[0] if isinstance(cost, (list, tuple)) else cost
    return float(cost.get("flops", 0.0)) / 1e9


def _flops(method, chunk_patches):
    """GFLOP per patch of the networks ``method`` runs (None: no network)."""
    from sphere_jax.bundles import inference
    from sphere_jax.models import shipped
    if method not in NETWORKS:
        return None
    total = 0.0
    for kind, what in NETWORKS[method]:
        b = inference.cached_bundle(shipped.bundle_path(kind, required=True))
        x = chunk_patches[:, :b.config.data.n_points]
        if what == "orient":
            total += unrolled_gflop(b._orient_fn, x) / len(x)
        elif method in ("lead_compass", "lead_modes"):    # LEAD in given frames
            frames = np.broadcast_to(np.eye(3, dtype=np.float32), (len(x), 3, 3))
            total += unrolled_gflop(b._describe_fn, x, frames) / len(x)
        else:
            total += unrolled_gflop(b._describe_fn, x) / len(x)
    return total


def register_time(method, keypoints, files):
    """``(seconds, result, load seconds)`` of :func:`sphere_jax.align.register` end to end on
    the pair of ``files`` (source, target), files read included."""
    from sphere_jax import align
    from sphere_jax.data.readers import io
    t0 = time.perf_counter()
    src, dst = (io.read_points(f).points for f in files)
    load_s = time.perf_counter() - t0
    result = align.register(src, dst, method=method, n_keypoints=keypoints)
    return time.perf_counter() - t0, result, load_s


def measure(method, keypoints):
    """The record of one method (run in a fresh process by :func:`run`)."""
    from sphere_jax.eval import timing
    from sphere_jax.features import methods
    from sphere_jax.models import shipped
    frag, files = fragments(keypoints)
    register_s, result, load_s = register_time(method, keypoints, files)
    bundles = shipped.defaults()
    describe = methods.descriptor(method, 0.30, bundles)
    # A first pass over the same keypoints: compiled programs, and the one-time costs of a
    # first large call (a first SHOT pass took 0.89 ms per keypoint, the next 0.23).
    describe(frag)
    with timing.Stopwatch() as watch:
        describe(frag)
    ms = 1e3 * watch.seconds / len(frag.keypoints)
    rng = np.random.default_rng(0)
    patches = (rng.normal(size=(256, 1225, 3)) * 0.4).astype(np.float32)
    gflop = _flops(method, patches)
    rss_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2
    return {"method": method, "keypoints": len(frag.keypoints), "ms_per_keypoint": round(ms, 3),
            "others_cpu": None if watch.others is None else round(watch.others, 3),
            "gflop": gflop, "peak_rss_gb": round(rss_gb, 2), "register_s": round(register_s, 1),
            "register_ok": result.ok,
            # register describes a share of the keypoints first (pipeline.PROGRESSIVE_SHARES)
            "register_described": [d for d, _ in result.keypoints],
            "register_stages": {"load": round(load_s, 2),
                                **{k: round(v, 2) for k, v in result.seconds.items()}}}


if __name__ == "__main__":
    from sphere_jax import compile_cache
    compile_cache.enable()                       # $SPHERE_JAX_COMPILE_CACHE, set by run()
    if sys.argv[3:] == ["warm"]:
        seconds = register_time(sys.argv[1], int(sys.argv[2]), pair_files())[0]
        print(json.dumps({"register_s": round(seconds, 1)}))
    else:
        print(json.dumps(measure(sys.argv[1], int(sys.argv[2]))))
