"""Registration suite: one 3DMatch pair (kitchen 0–5 of the real scans, else the first
synthetic pair) with 5000 keypoints per fragment, evaluated end to end with FPFH, SHOT and LEAD
(the shipped bundle): seconds per stage and in total, JIT compilation included (target: 60 s on
2 cores)."""
from __future__ import annotations

import json
import os
import sys
import time

from sphere_jax import paths
from sphere_jax.data import scan_roots
from sphere_jax.data.readers import threedmatch
from sphere_jax.eval import pair_sets, registration
from sphere_jax.features import methods as method_lib
from sphere_jax.models import shipped


def run(keypoints=5000, methods=("fpfh", "shot", "lead"), **_):
    """Seconds per stage of one pair's evaluation, end to end (compilation included)."""
    kitchen = paths.real_data("3dmatch", "7-scenes-redkitchen")
    if kitchen and os.path.isdir(kitchen):
        pair_set = pair_sets.fragment_scene(threedmatch.load_fragment_scene(kitchen,
                                                                      kitchen + "-evaluation"))
        pair = (0, 5)
    else:
        pair_set = pair_sets.find_pair_sets(scan_roots.default_scan_root())[0]
        pair = pair_set.pairs[0]
    bundles = {k: shipped.bundle_path(k) for k in ("lead", "compass", "sound")}
    records, total = [], time.perf_counter()

    def stage(name, fn):
        t0 = time.perf_counter()
        out = fn()
        records.append({"pair": f"{pair_set.name} {pair}", "stage": name,
                        "seconds": round(time.perf_counter() - t0, 2)})
        print(json.dumps(records[-1]), file=sys.stderr, flush=True)
        return out

    frags = stage("prepare (voxel, normals, keypoints)", lambda: {
        k: pair_sets.prepare(pair_set, k, n_keypoints=keypoints) for k in pair})
    for m in methods:
        describe = method_lib.descriptor(m, 0.30, bundles, 0.15)
        desc = stage(f"{m}: describe 2x{keypoints}", lambda: {k: describe(f)
                                                            for k, f in frags.items()})
        row = stage(f"{m}: match + RANSAC", lambda: registration.match_pair(
            frags[pair[0]], frags[pair[1]], desc[pair[0]], desc[pair[1]],
            pair_set.transforms[pair]))
        records[-1]["seconds"] = f"{records[-1]['seconds']} (RRE {row['rre_deg']:.1f} deg)"
    records.append({"pair": f"{pair_set.name} {pair}", "stage": "total",
                    "seconds": round(time.perf_counter() - total, 2)})
    return records
