"""Defaults shared by the evaluation configs (data preparation, bundles, output)."""
from __future__ import annotations

import ml_collections

from sphere_jax import checks
from sphere_jax.models import shipped

SIZES = ("", "quick", "tiny")


def base(arg) -> ml_collections.ConfigDict:
    size = arg or ""
    if size not in SIZES:
        raise checks.ConfigError("the config argument (after the colon)", f"one of {SIZES}",
                                 arg)
    c = ml_collections.ConfigDict()
    c.size = size or "full"
    c.seed = 0
    c.data = ml_collections.ConfigDict(dict(
        root="",              # empty: the embedded synthetic scenes; else 3DMatch/Stanford layout
        gt="",                # ground truth elsewhere (3DLoMatch): <gt>/<scene>-evaluation/gt.log
        voxel=0.02,           # 2 cm voxel grid (seed 4.3)
        normal_k=17,          # normals from 17 neighbours
        n_keypoints=5000,     # per scan, seeded random (release keypoint files win if present)
        radius=0.30,          # support radius of every local method (3DMatch)
        scenes="",            # comma-separated scene names to keep; empty: all
        max_pairs=0,          # per scene; 0: every pair
    ))
    c.rotate = False          # the rotated variant: every scan turned by a seeded rotation
    c.methods = ""
    c.bundle = ""             # one bundle overriding the default of its kind
    c.bundles = ml_collections.ConfigDict(shipped.defaults())    # kind -> bundle folder
    c.chunk = ml_collections.config_dict.placeholder(int)    # None: each bundle's infer_chunk
    if size == "quick":
        c.data.update(n_keypoints=2500, max_pairs=8)
    elif size == "tiny":
        c.data.update(n_keypoints=300, max_pairs=2, scenes="")
    return c
