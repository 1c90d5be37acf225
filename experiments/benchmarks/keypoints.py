"""Keypoints suite: what ``register`` gains by describing half its keypoints first.

On the 27 redkitchen pairs (14 3DMatch, 13 3DLoMatch; real scans only), for one method
(``--only``, default LEAD-PN): :func:`sphere_jax.align.register` with all keypoints at once at
``--keypoints`` and at half as many (``progressive=False`` both: a random half of a random draw
is a random draw), each pair scored against its ground truth (RRE < 15°, RTE < 0.3 m). One
record per pair: whether each registration succeeded (``ok``), was right, its RANSAC inliers and
seconds, and what ``progressive=True`` returns — the half's result when it is ``ok`` with at
least :data:`~sphere_jax.align.CONFIDENT_INLIERS` inliers, else the whole one — with its
seconds (the half's, plus the whole's when it goes on). The table is per benchmark.
"""
from __future__ import annotations

import json
import os
import sys
import time
import warnings

METHOD = "lead_pn"


def pair_sets():
    """``[(benchmark, FragmentScene)]``: redkitchen's 3DMatch and 3DLoMatch pairs."""
    from sphere_jax import paths
    from sphere_jax.data.readers import threedmatch
    kitchen = paths.real_data("3dmatch", "7-scenes-redkitchen")
    if not (kitchen and os.path.isdir(kitchen)):
        raise FileNotFoundError("the keypoints suite needs the real redkitchen scans "
                                "(../shared/data/3dmatch/7-scenes-redkitchen)")
    lomatch = paths.real_data("3dmatch", "3DLoMatch", "7-scenes-redkitchen-evaluation")
    return [("3DMatch", threedmatch.load_fragment_scene(kitchen)),
            ("3DLoMatch", threedmatch.load_fragment_scene(kitchen, lomatch))]


def pair_record(method, source, target, t_gt, keypoints):
    """Both registrations of one pair (source onto target) and the progressive outcome."""
    from sphere_jax import align
    from sphere_jax.eval import registration
    rec = {}
    for name, k in (("half", (keypoints + 1) // 2), ("whole", keypoints)):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = align.register(source, target, method=method, n_keypoints=k, progressive=False)
        rec[name] = {"ok": r.ok, "right": registration.registered(*registration.rre_rte(
                         r.transform, t_gt)), "inliers": int(r.inliers),
                     "confident": r.confident, "seconds": round(time.perf_counter() - t0, 1)}
    half, whole = rec["half"], rec["whole"]
    stop = half["confident"]                      # register's own rule for stopping at half
    rec["progressive"] = {"stopped_at_half": stop, "right": half["right"] if stop else
                          whole["right"], "seconds": half["seconds"] if stop else
                          round(half["seconds"] + whole["seconds"], 1)}
    return rec


def run(keypoints=5000, only=None, **_):
    """One record per pair (printed as it comes), then one summary row per benchmark."""
    from sphere_jax.data.readers import io
    method = only or METHOD
    clouds, rows = {}, []
    for bench, scene in pair_sets():
        pairs = []
        for (i, j), t_gt in sorted(scene.transforms.items()):
            for k in (i, j):
                clouds.setdefault(k, io.read_points(scene.fragment_path(k)).points)
            rec = {"benchmark": bench, "pair": [i, j],
                   **pair_record(method, clouds[j], clouds[i], t_gt, keypoints)}
            print(json.dumps(rec), file=sys.stderr, flush=True)
            pairs.append(rec)
        rows.append(summary(method, bench, pairs, keypoints))
    return rows


def summary(method, bench, pairs, keypoints):
    """The benchmark's row: pairs registered right and seconds, per way of registering, and
    the inliers of the half's wrong but ``ok`` registrations (what the threshold must stop)."""
    right = lambda way: sum(p[way]["right"] for p in pairs)
    secs = lambda way: round(sum(p[way]["seconds"] for p in pairs), 1)
    return {"method": method, "benchmark": bench, "pairs": len(pairs),
            f"right_{(keypoints + 1) // 2}": right("half"), f"right_{keypoints}": right("whole"),
            "right_progressive": right("progressive"),
            "stopped_at_half": sum(p["progressive"]["stopped_at_half"] for p in pairs),
            f"seconds_{keypoints}": secs("whole"), "seconds_progressive": secs("progressive"),
            "wrong_ok_half_inliers": sorted(p["half"]["inliers"] for p in pairs
                                            if p["half"]["ok"] and not p["half"]["right"])}
