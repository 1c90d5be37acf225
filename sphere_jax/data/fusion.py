"""Fragments from a posed RGB-D sequence, made as 3DMatch made its fragments from runs of
consecutive depth frames: each frame back-projected by its pose into the frame of the run's
first camera, and the union averaged per 1 cm voxel.

Averaging over many views evens out the sensor's depth noise and fills the holes of single
frames, so the surfaces a network trains on look like the benchmark's fragments rather than
like raw depth images. (3DMatch integrated a TSDF volume; open3d 0.20's TSDF integration
extracts no surface on this machine's build, so the voxel mean stands in for it.) Fragments are
cached under :func:`sphere_jax.paths.cache_root`, keyed by the folder and the parameters, so a
training run fuses a sequence once.
"""
from __future__ import annotations

import hashlib
import json
import os

import numpy as np
from tqdm import tqdm

from sphere_jax import paths
from sphere_jax.data import o3d_convert
from sphere_jax.data.readers import io, rgbd

# Averaging voxel, and depth beyond which a Kinect-like sensor's noise (∝ z²) exceeds ~1 cm.
FUSION_VOXEL, DEPTH_TRUNC = 0.01, 3.5
SOURCE_FILE = "source.json"      # beside the cached fragments: what they were fused from


def fuse(sequence: rgbd.FrameSequence, frames, depth_scale=1000.0):
    """Points ``[M, 3]`` (float32) of ``frames`` (indices into the sequence) averaged per
    ``FUSION_VOXEL`` cell, in the frame of the first of them (``p_world = A · p``, ``A`` its
    pose)."""
    a_inv = np.linalg.inv(sequence.poses[frames[0]])
    clouds = [rgbd.read_rgbd_frame(None, sequence.depth[f], sequence.intrinsics,
                                   a_inv @ sequence.poses[f], depth_scale, DEPTH_TRUNC).points
              for f in frames]
    pc = o3d_convert.point_cloud(np.concatenate(clouds))
    return np.asarray(pc.voxel_down_sample(FUSION_VOXEL).points, np.float32)


def fragment_runs(n_frames, frames_per_fragment, stride):
    """Start-to-end runs of consecutive frames, one per fragment (the last run may be shorter
    but keeps at least half the length)."""
    if frames_per_fragment < 1 or stride < 1:
        raise ValueError(f"frames_per_fragment and stride must be ≥ 1, got "
                         f"{frames_per_fragment} and {stride}")
    runs = [list(range(s, min(s + frames_per_fragment, n_frames)))
            for s in range(0, n_frames, stride)]
    return [r for r in runs if len(r) >= min(n_frames, max(1, frames_per_fragment // 2))]


def sequence_fragments(folder, frames_per_fragment=25, stride=25, cache_dir=None):
    """Paths of the fused fragments (``cloud_bin_K.ply``) of the RGB-D sequence in ``folder``,
    fused on first use and cached."""
    seq = rgbd.read_frame_sequence(folder)
    runs = fragment_runs(len(seq), frames_per_fragment, stride)
    key = json.dumps({"folder": os.path.abspath(str(folder)), "runs": runs,
                      "fusion": [FUSION_VOXEL, DEPTH_TRUNC]})
    out = os.path.join(cache_dir or os.path.join(paths.cache_root(), "fused"),
                       os.path.basename(os.path.abspath(str(folder))) + "-" +
                       hashlib.sha1(key.encode()).hexdigest()[:10])
    files = [os.path.join(out, f"cloud_bin_{k}.ply") for k in range(len(runs))]
    if all(os.path.isfile(f) for f in files):
        return files
    os.makedirs(out, exist_ok=True)
    io.atomic_write(os.path.join(out, SOURCE_FILE), key.encode())
    for k, run in enumerate(tqdm(runs, desc=f"fusing {os.path.basename(str(folder))}",
                                 unit="fragment")):
        if not os.path.isfile(files[k]):
            io.write_ply(files[k], fuse(seq, run))   # atomic: an interrupted fuse is redone
    return files


def fused_source(folder):
    """The RGB-D folder whose fragments ``folder`` caches, or None for any other folder."""
    path = os.path.join(str(folder), SOURCE_FILE)
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return json.load(f)["folder"]
