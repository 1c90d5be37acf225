"""Keypoints suite: what ``register`` gains by describing a share of its keypoints first.

On the 27 redkitchen pairs (14 3DMatch, 13 3DLoMatch; real scans only), for one method
(``--only``, default LEAD-PN): :func:`sphere_jax.align.register` with all keypoints at once at
each share of ``--keypoints`` in
:data:`~sphere_jax.registration.pipeline.PROGRESSIVE_SHARES` (a quarter, half and all;
``progressive=False`` each: a random share of a random draw is a random draw), each pair
scored against its ground truth (RRE < 15°, RTE < 0.3 m). One record per pair: whether each
registration succeeded (``ok``), was right, its RANSAC inliers, mutual matches, ICP
fitness and seconds, and what ``progressive=True`` returns — the first share's result that is
``confident`` (:attr:`~sphere_jax.registration.pipeline.Registration.confident`), else the
whole one — with its seconds: the stopping share's, plus the matching, RANSAC and ICP of the
shares before it (``register`` describes each keypoint once). The table is per benchmark.
"""
from __future__ import annotations

import json
import math
import os
import sys
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


def shares(keypoints):
    """The keypoint counts ``register`` describes in turn
    (:data:`~sphere_jax.registration.pipeline.PROGRESSIVE_SHARES` of ``keypoints``)."""
    from sphere_jax.registration import pipeline
    return pipeline.share_counts(keypoints)


def pair_record(method, source, target, t_gt, keypoints):
    """Every share's registration of one pair (source onto target), keyed by its keypoint
    count, and the progressive outcome."""
    from sphere_jax import align
    from sphere_jax.eval import registration
    rec, spent = {}, 0.0
    for k in shares(keypoints):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = align.register(source, target, method=method, n_keypoints=k, progressive=False)
        rec[str(k)] = {"ok": r.ok, "right": registration.registered(*registration.rre_rte(
                           r.transform, t_gt)), "inliers": int(r.inliers),
                       "matches": int(r.matches),     # fitness: null without ICP (strict JSON)
                       "fitness": round(r.fitness, 4) if math.isfinite(r.fitness) else None,
                       "confident": r.confident, "seconds": round(sum(r.seconds.values()), 1)}
        if "progressive" not in rec and (r.confident or k == keypoints):
            rec["progressive"] = {"stopped_at": k, "right": rec[str(k)]["right"],
                                  "seconds": round(spent + sum(r.seconds.values()), 1)}
        spent += sum(v for stage, v in r.seconds.items() if stage != "descriptors")
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
    """The benchmark's row: pairs registered right per share and progressively, where the
    progressive ones stopped, the seconds at all keypoints and progressively, and the
    inliers of each share's wrong but ``ok`` registrations (what the threshold must stop)."""
    counts = shares(keypoints)
    secs = lambda get: round(sum(get(p)["seconds"] for p in pairs), 1)
    stops = [p["progressive"]["stopped_at"] for p in pairs]
    return {"method": method, "benchmark": bench, "pairs": len(pairs),
            **{f"right_{k}": sum(p[str(k)]["right"] for p in pairs) for k in counts},
            "right_progressive": sum(p["progressive"]["right"] for p in pairs),
            "stopped_at": ", ".join(f"{k}: {stops.count(k)}" for k in counts),
            f"seconds_{keypoints}": secs(lambda p: p[str(keypoints)]),
            "seconds_progressive": secs(lambda p: p["progressive"]),
            "wrong_ok_inliers": "; ".join(
                f"{k}: " + (", ".join(str(i) for i in sorted(
                    p[str(k)]["inliers"] for p in pairs
                    if p[str(k)]["ok"] and not p[str(k)]["right"])) or "none")
                for k in counts)}
