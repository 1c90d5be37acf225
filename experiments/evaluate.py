"""Evaluate a trained bundle on 3DMatch-layout scenes and print a table:
``python -m experiments.evaluate --bundle=runs/sound_cpu/bundle [--data=DIR]``.

Descriptor bundles (LEAD, LEAD-PN, SOUND): feature-match recall and mean inlier ratio per
scene; LRF bundles (Compass, SOUND): LRF repeatability, next to FLARE in the same run. The
default data are the embedded synthetic scenes.
"""
from __future__ import annotations

import argparse
import glob
import json
import os

import numpy as np

from sphere_jax import api
from sphere_jax.data import datasets, pipeline
from sphere_jax.eval import registration


def flare_orient(radius):
    def orient(points, keypoints):
        p = api.extract_unit_patches(points, keypoints, radius, 1225)
        return api.run_chunked(api.FLARE_BATCH, p, 256)
    return orient


def evaluate(bundle_path, data_root=None, n_keypoints=1000, radius=None, voxel=0.02):
    bundle = api.load_bundle(bundle_path)
    radius = radius or bundle.config.data.radius
    root = data_root or pipeline.default_scan_root()
    scenes = [datasets.load_fragment_scene(os.path.dirname(p))
              for p in sorted(glob.glob(os.path.join(root, "*", "cloud_bin_0.ply")))]
    rows = []
    for scene in scenes:
        row = {"scene": scene.name, "pairs": len(scene.pairs)}
        fragments = registration.load_fragments(scene, voxel)
        if bundle.kind in ("lead", "lead_pn", "sound"):
            per_pair, recall = registration.feature_match_recall(
                lambda p, k: bundle.describe(p, k, radius=radius), scene, fragments, n_keypoints)
            row.update(fmr=recall, inlier_ratio=float(np.mean([r["inlier_ratio"]
                                                               for r in per_pair])))
        if bundle.kind in ("compass", "sound"):
            row["lrf_rep"] = registration.lrf_repeatability(
                lambda p, k: bundle.orient(p, k, radius=radius), scene, fragments,
                n_keypoints // 2, voxel)
            row["flare_rep"] = registration.lrf_repeatability(
                flare_orient(radius), scene, fragments, n_keypoints // 2, voxel)
        rows.append(row)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bundle", required=True)
    parser.add_argument("--data", default=None, help="folder of 3DMatch-layout scenes")
    parser.add_argument("--keypoints", type=int, default=1000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = evaluate(args.bundle, args.data, args.keypoints)
    if args.json:
        print(json.dumps(rows))
        return
    cols = list(dict.fromkeys(k for r in rows for k in r))
    fmt = lambda v: f"{v:.3f}" if isinstance(v, float) else str(v)
    cells = [[fmt(r.get(c, "")) for c in cols] for r in rows]
    widths = [max(len(c), *(len(x[i]) for x in cells)) for i, c in enumerate(cols)]
    print("| " + " | ".join(c.ljust(w) for c, w in zip(cols, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for x in cells:
        print("| " + " | ".join(v.ljust(w) for v, w in zip(x, widths)) + " |")


if __name__ == "__main__":
    main()
