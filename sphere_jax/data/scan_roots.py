"""The scan files of a training config's ``data.root``: its comma-separated entries (folders,
scan files, the synthetic rooms of a seed, paths under the real scans), each read into a list
of scans (posed RGB-D sequences fused first), voxelised, and labelled by where they came from
for the bundle's statement; or the same entries read from a pack, voxelised once for a machine
without the renderer, open3d or the real scans.
"""
from __future__ import annotations

import glob
import json
import os
import re

import numpy as np

from sphere_jax import checks, paths, workdirs
from sphere_jax.data import fusion, patches
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import io, ply, rgbd


def find_scans(root):
    """Scan files under ``root``: a scan file itself (any suffix the readers read); the fused
    fragments of a posed RGB-D sequence (:mod:`sphere_jax.data.fusion`); 3DMatch fragments
    (``cloud_bin_K.ply``) if there are any; else every .ply / .pcd, recursively (sorted)."""
    root = str(root)
    if os.path.isfile(root) and root.lower().endswith(io.SUFFIXES):
        return [root]
    if not os.path.isdir(root):
        raise checks.MissingError(f"data root {root!r} is neither a scan file nor a folder")
    if rgbd.is_frame_sequence(root):
        return fusion.sequence_fragments(root)
    frags = sorted(glob.glob(os.path.join(root, "**", "cloud_bin_*.ply"), recursive=True))
    if frags:
        return frags
    found = sorted(p for ext in ("ply", "pcd")
                   for p in glob.glob(os.path.join(root, "**", f"*.{ext}"), recursive=True))
    if not found:
        raise checks.MissingError(f"no .ply or .pcd scans under {root!r}")
    return found


def scan_groups(roots, pack=""):
    """Scan files of each entry of a comma-separated list of folders (or scan files), one list
    per entry (:func:`resolve_root` reads each entry), so real scans can be added to the
    synthetic ones: ``embedded,embedded:1,/data/3dmatch/demo``. ``pack``: a folder of
    :func:`pack_scans` that holds every entry, read instead (:func:`packed_folders`)."""
    if pack:
        return [find_scans(folder) for folder in packed_folders(roots, pack)]
    return [find_scans(resolve_root(r)) for r in root_entries(roots)]


def resolve_root(entry):
    """The folder or file a ``data.root`` entry names: ``embedded`` the default synthetic
    rooms, ``embedded:N`` the training rooms of seed N (generated on first use),
    ``shared/<rel>`` a path under the real scans (``../shared/data``: the same config on
    every machine), anything else a path."""
    entry = str(entry)
    if entry in DEFAULT_ROOMS:
        synthetic.ensure_default_data()
    elif entry.startswith("embedded:"):
        synthetic.ensure_training_rooms(_rooms_seed(entry))
    return entry_path(entry)


DEFAULT_ROOMS = ("embedded", "embedded:0")      # the embedded default data's rooms


def _rooms_seed(entry):
    seed = entry[len("embedded:"):]
    if not seed.isdigit():
        raise checks.ConfigError("a data.root entry 'embedded:N'", "an integer seed N", entry)
    return int(seed)


def entry_path(entry):
    """Where a ``data.root`` entry's scans are (or will be, for synthetic data not yet
    generated): :func:`resolve_root` without generating anything."""
    entry = str(entry)
    if entry in DEFAULT_ROOMS:
        return os.path.join(synthetic.default_data_dir(0), "3dmatch")
    if entry.startswith("embedded:"):
        return synthetic.training_rooms_dir(_rooms_seed(entry))
    if entry.startswith("shared/"):
        found = paths.real_data(*entry[len("shared/"):].split("/"))
        if found is None:
            raise checks.MissingError(f"data.root entry {entry!r} is under the real scans, "
                                      f"which are not here (../shared/data, or "
                                      f"$SPHERE_JAX_REAL_DATA)")
        return found
    return entry


def root_entries(roots):
    """The entries of a comma-separated ``data.root`` (``['embedded']`` for an empty one)."""
    return [r.strip() for r in str(roots).split(",") if r.strip()] or ["embedded"]


def scan_paths(roots):
    """The scan files of :func:`scan_groups`, in one list."""
    return [p for group in scan_groups(roots) for p in group]


def parse_weights(text, n_groups):
    """``data.root_weights``: '' (every keypoint equally likely) or one non-negative number per
    entry of ``data.root`` (the share of each entry's keypoints in a batch), normalised."""
    if not str(text).strip():
        return None
    try:
        w = np.array([float(x) for x in str(text).split(",")], np.float64)
    except ValueError:
        raise ValueError(f"data.root_weights must be comma-separated numbers, got {text!r}")
    if len(w) != n_groups or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError(f"data.root_weights must be {n_groups} finite non-negative numbers "
                         f"(one per data.root entry) with a positive sum, got {text!r}")
    return w / w.sum()


def default_scan_root():
    return synthetic.default_root("3dmatch")


# ---- packed scans: the training data, voxelised once, for another machine -------------------

PACK_INDEX = "SOURCE.json"


def scan_folder_label(path):
    """What a scan's folder is, for a bundle's statement of its training data: the portable
    folder (:func:`sphere_jax.paths.portable`), the RGB-D sequence a fused fragment came from,
    or, for a packed scan, the folder it was packed from."""
    index = _pack_index(os.path.dirname(path))
    if index is not None:
        return index["scans"][os.path.basename(path)] + f" (packed at {index['voxel']} m)"
    rgbd_folder = fusion.fused_source(os.path.dirname(path))
    return (paths.portable(rgbd_folder) + " (fused RGB-D)" if rgbd_folder
            else paths.portable(os.path.dirname(path)))


def load_scan(path, voxel):
    """Points ``[N, 3]`` of a scan on the ``voxel`` grid (a scan packed at that voxel as is)."""
    index = _pack_index(os.path.dirname(path))
    pts = io.read_points(path).points
    if index is not None and float(index["voxel"]) == float(voxel):
        return pts.astype(np.float32)
    return patches.voxel_downsample(pts, voxel)


def pack_scans(roots, voxel, out_dir):
    """Write each entry of ``roots`` (a ``data.root`` list) voxelised at ``voxel`` as binary PLY
    scans in ``out_dir/<k>-<name>/``, with a ``SOURCE.json`` naming each scan's origin; the
    pack's folders, in the same order, are a ``data.root`` that trains on the same keypoints
    without open3d, the RGB-D fusion or the renderer (the embedded rooms: 164 MB rendered,
    a tenth of it packed). Returns ``{folder: scans}``."""
    names = root_entries(roots)
    voxel = checks.positive(voxel, "voxel")
    written = {}
    for k, (name, group) in enumerate(zip(names, scan_groups(roots))):
        slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", os.path.basename(name.rstrip("/")) or name)
        folder = workdirs.prepare(os.path.join(out_dir, f"{k}-{slug}"), "out_dir")
        index = {"entry": name, "voxel": voxel, "scans": {}}
        for i, path in enumerate(group):
            file = f"scan_{i:03d}.ply"
            ply.write_ply(os.path.join(folder, file), load_scan(path, voxel))
            index["scans"][file] = scan_folder_label(path)
        io.atomic_write(os.path.join(folder, PACK_INDEX), json.dumps(index, indent=1).encode())
        written[folder] = len(group)
    return written


def packed_folders(roots, pack):
    """The folders of the pack ``pack`` (:func:`pack_scans`) that hold the entries of
    ``roots``, in their order: the same data.root read on a machine without the renderer,
    open3d or the real scans (:class:`~sphere_jax.checks.ConfigError` for a pack that is not
    there or lacks an entry, naming it)."""
    if not os.path.isdir(str(pack)):
        raise checks.ConfigError("config.train.pack", "a folder made by python -m "
                                 "experiments.make_data --pack=ROOTS --out=DIR", pack)
    held = {}
    for index in sorted(glob.glob(os.path.join(str(pack), "*", PACK_INDEX))):
        folder = os.path.dirname(index)
        held.setdefault(_pack_index(folder).get("entry"), folder)
    missing = [e for e in root_entries(roots) if e not in held]
    if missing:
        raise checks.ConfigError(f"config.train.pack {str(pack)!r} holds no pack of the "
                                 f"data.root entries {missing} (it holds "
                                 f"{sorted(map(str, held))})")
    return [held[e] for e in root_entries(roots)]


def _pack_index(folder):
    path = os.path.join(folder, PACK_INDEX)
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return json.load(f)
