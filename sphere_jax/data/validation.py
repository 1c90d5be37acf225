"""Validation pairs from posed RGB-D sequences of training scenes: fragments fused as training
fuses them (:mod:`sphere_jax.data.fusion`), written as a 3DMatch scene whose ``gt.log`` comes
from the cameras' poses.

Settings of a learned frame or descriptor (data shares, radius, hypotheses) are chosen on pairs
like these, never on an evaluation scene. The sequences of one scene must share a world frame
(7-Scenes' sequences do: their poses were registered to one model), so fragments of different
sequences pair as well as consecutive runs of one sequence.
"""
from __future__ import annotations

import json
import os

import numpy as np

from sphere_jax import checks, files, workdirs
from sphere_jax.data import fusion, patches
from sphere_jax.data.poses import overlap, relative
from sphere_jax.data.readers import io, rgbd, threedmatch

# A pair: more than 10 % of one fragment lies on the other (2 voxels apart), the lower bound of
# 3DLoMatch (3DMatch's pairs overlap by more than 30 %): the validation pairs of one scene are
# few, and low overlap is where frames fail most.
MIN_OVERLAP, OVERLAP_VOXEL = 0.10, 0.02


def sequence_folders(root):
    """The posed RGB-D sequences at ``root``: the folder itself, else its sub-folders that are
    sequences (sorted); :class:`~sphere_jax.checks.MissingError` when there is none."""
    root = str(root)
    if rgbd.is_frame_sequence(root):
        return [root]
    found = sorted(os.path.join(root, d) for d in os.listdir(root) if
                   rgbd.is_frame_sequence(os.path.join(root, d))) if os.path.isdir(root) else []
    if not found:
        raise checks.MissingError(f"{root!r} holds no posed RGB-D sequence (3DMatch toolbox "
                                  f"layout or open3d's), nor do its sub-folders")
    return found


def write_scene(root, out_dir, frames_per_fragment=25, stride=25, min_overlap=MIN_OVERLAP):
    """Fuse every sequence under ``root`` into fragments (runs of ``frames_per_fragment``
    frames every ``stride``), each in the frame of its run's first camera, and write them as
    ``out_dir/cloud_bin_K.ply`` with ``gt.log`` (``p_i = T_ij p_j`` from the poses) and
    ``gt_overlap.log`` for every pair overlapping by more than ``min_overlap``. Returns a
    summary (also written as ``validation.json``)."""
    folders = sequence_folders(root)
    out = workdirs.prepare(str(out_dir), "out_dir")
    clouds, poses, sources = [], [], []
    for folder in folders:
        seq = rgbd.read_frame_sequence(folder)
        for run in fusion.fragment_runs(len(seq), frames_per_fragment, stride):
            clouds.append(fusion.fuse(seq, run))
            poses.append(seq.poses[run[0]])
            sources.append({"sequence": os.path.abspath(folder), "frames": run})
    poses = np.stack(poses)
    grid = [patches.voxel_downsample(c, OVERLAP_VOXEL) for c in clouds]
    transforms, overlaps = {}, {}
    for i in range(len(clouds)):
        for j in range(i + 1, len(clouds)):
            t = relative(poses, j, i)
            r = overlap(grid[i], grid[j], t, OVERLAP_VOXEL)
            if r > min_overlap:
                transforms[(i, j)], overlaps[(i, j)] = t, r
    if not transforms:
        raise checks.MissingError(f"no two of the {len(clouds)} fragments fused from {root!r} "
                                  f"overlap by more than {min_overlap:.0%}")
    for k, cloud in enumerate(clouds):
        io.write_ply(os.path.join(out, f"cloud_bin_{k}.ply"), cloud)
    threedmatch.write_gt_log(os.path.join(out, "gt.log"), transforms, len(clouds))
    threedmatch.write_gt_overlap(os.path.join(out, "gt_overlap.log"), overlaps)
    summary = {"source": os.path.abspath(str(root)), "fragments": sources,
               "frames_per_fragment": frames_per_fragment, "stride": stride,
               "pairs": len(transforms), "min_overlap": min_overlap}
    files.atomic_write(os.path.join(out, "validation.json"),
                       json.dumps(summary, indent=1).encode())
    return summary
