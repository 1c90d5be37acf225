"""Defaults shared by the experiment configs (data, training loop, checkpoints)."""
from __future__ import annotations

import ml_collections

from sphere_jax import checks
from sphere_jax.data import shape_source

# 'mid' sits between: the seed's ablation (Table 4.5) kept 0.922 of the best LEAD recall with
# three SO(3) layers at input bandwidths 12, 8, 6 (its configuration F) at 0.64 of the time
# (the shipped LEAD reads 8, 8, 6: its first grid is 16³, not 24³; configs/lead.py), and
# a repeatable frame needs finer cells than B = 8's 22.5° (both axes within 14° at rho = 0.97),
# so Compass decides at B = 12 (15° cells, refined by the soft-argmax): deciding at B = 8 halves
# its time and loses 22 % of its repeatability (docs/performance.md).
SIZES = ("paper", "mid", "small", "tiny")

# Inference chunk of the B = 24 'paper' Compass and SOUND: their SO(3) spectra take ~40 MB per
# patch (SOUND at chunk 256 peaked at 10 GB), so two chunks of 64 in flight stay well inside
# 24 GB.
B24_INFER_CHUNK = 64


# The shipped bundles' training scans: the synthetic training rooms of seeds 1-4 (eight rooms,
# 96 fragments; the embedded default rooms of seed 0 are the main job's evaluation scenes).
MID_ROOT = "embedded:1,embedded:2,embedded:3,embedded:4"
# Of the clean real scans of ../shared/data only open3d's RGB-D frames (one fused fragment)
# reached a 2 cm voxel and 30 cm supports (open3d's Feature fragments, of no documented scene,
# are held out: data/held_out.py). As a fifth of Compass's batches it raised the redkitchen
# repeatability by 11 % at B = 8 and B = 12 (docs/training.md), so the shipped Compass trains
# on it; the descriptors have not been trained with it.
REAL_SCAN = "shared/open3d_testdata/RGBD"
# The shape task's 'mid' data: ModelNet40's whole train release (PointNet's HDF5, 9843 shapes of
# 1024 points); the official test split is not in ../shared/data, so ShapeSource holds one out.
MODELNET_TRAIN = "shared/modelnet40/pointnet_1024"


def shape_splits(c):
    """The splits of every shape task (whole-shape Compass and the classifiers alike,
    ``shape_source.ShapeSource``): each k-th shape of a class tests where the set has no test
    split, each k-th of the rest validates."""
    c.data.holdout_every = shape_source.HOLDOUT_EVERY
    c.data.val_every = shape_source.HOLDOUT_EVERY
    return c


def check_size(arg):
    size = arg or "paper"
    if size not in SIZES:
        raise checks.ConfigError("the config argument (after the colon)", f"one of {SIZES}",
                                 arg)
    return size


def base(size: str) -> ml_collections.ConfigDict:
    c = ml_collections.ConfigDict()
    c.seed = 0
    c.size = size
    c.data = ml_collections.ConfigDict(dict(
        root="embedded:1",        # comma-separated folders, scan files, 'embedded:N' (the
                                  # synthetic training rooms of seed N) or 'shared/<rel>'
                                  # (scan_roots.resolve_root)
        root_weights="",          # share of each root entry in a batch; '': by keypoint count
        voxel=0.02,               # fragments voxel-downsampled at 2 cm (seed 4.3)
        keypoint_leaf=0.10,       # one keypoint every 10 cm (seed 3.1.5)
        radius=0.30,              # support radius (3DMatch)
        n_points=1225,            # points per patch: drawn with replacement in training,
                                  # evenly when describing (data/supports.py)
        min_points=300,           # supports with fewer points are skipped
        val_fraction=0.1,         # keypoints held out for the validation loss
        occlusion=True,           # occlude the rotated copy (seed 3.1.5)
        copy_draw="patch",        # the copy's points: 'patch' (the seed's), 'support' (a
                                  # second draw from the whole support) or 'scan' (another
                                  # scan of the scene, by its ground truth: data/poses.py)
        copy_jitter=0.0,          # Gaussian noise on the copy (std, units of the radius)
        allow_evaluation_scenes=False,   # True: an evaluation-scene experiment, recorded
                                         # (sphere_jax/data/held_out.py)
    ))
    # Patches per jitted inference call (inference.Bundle.orient/describe); memory grows with it and
    # with the chunks run at a time (parallel.run_chunked).
    c.infer_chunk = 256
    c.train = ml_collections.ConfigDict(dict(
        steps=50_000, batch_size=8, learning_rate=1e-3,
        schedule="constant",      # or 'warmup_cosine': warmup_steps up to learning_rate, then
        warmup_steps=0,           # a cosine decay to final_lr_fraction of it at `steps`
        final_lr_fraction=1.0,
        log_every=50, eval_every=1000,
        eval_batches=4, checkpoint_every=1000, keep_checkpoints=3,
        fused=True,               # spectral-domain training; False: layer-by-layer reference
        init_bundle="",           # continue a run from its committed bundle (another machine)
        finetune_bundle="",       # start from a bundle's weights at step 0 (other data)
        time_budget_s=0.0,        # > 0: stop (checkpoint, bundle) once the loop ran this long
        pack="",                  # read data.root from this pack (make_data --pack): another
                                  # machine, the same batches
        devices=0))               # data-parallel devices per host; 0: all local devices
    if size == "mid":
        c.data.n_points = 1024
        c.train.update(steps=20_000, log_every=50, eval_every=500, checkpoint_every=500)
    elif size == "small":
        c.data.n_points = 512
        c.train.update(steps=1500, log_every=25, eval_every=250, checkpoint_every=250)
    elif size == "tiny":
        c.data.update(n_points=64, min_points=20, keypoint_leaf=0.4)
        c.train.update(steps=3, batch_size=4, log_every=1, eval_every=2, eval_batches=1,
                       checkpoint_every=2)
    return c


def shipped_recipe(c, steps, batch_size, learning_rate=1e-3, real_scan=False):
    """Make ``c`` (a 'mid' config of a model trained on scans) the whole recipe of its shipped
    bundle: clean data (no scan of an evaluation scene; ``real_scan``: open3d's fused RGB-D
    frames as a fifth of every batch), steps, batch and the learning-rate schedule, so that
    ``python -m experiments.train --config=KIND:mid`` reproduces it."""
    c.data.root = MID_ROOT + (f",{REAL_SCAN}" if real_scan else "")
    if real_scan:
        c.data.root_weights = ",".join(["1"] * len(c.data.root.split(",")))
    c.train.update(steps=steps, batch_size=batch_size, learning_rate=learning_rate,
                   schedule="warmup_cosine", warmup_steps=200, final_lr_fraction=0.01)
    return c


def decoder_kwargs(size: str) -> dict:
    """Folding-decoder sizes shared by LEAD, LEAD-PN and SOUND ('paper': the model defaults)."""
    return {"paper": {}, "mid": dict(decoder_side=32, decoder_hidden=(512, 256, 128)),
            "small": dict(decoder_side=16, decoder_hidden=(256, 128, 64)),
            "tiny": dict(decoder_side=6, decoder_hidden=(16, 16, 8))}[size]
