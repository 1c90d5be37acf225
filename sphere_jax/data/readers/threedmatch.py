"""The 3DMatch layout: fragment scenes, ``gt.log`` / ``gt.info`` / ``gt_overlap.log``, fragment
``.info.txt`` poses and keypoint index files (also how 3DLoMatch and ETH are released).

Ground truth (CONVENTIONS.md §6, checked on the real files by the tests): ``gt.log`` entry
``(i, j)`` is a 4×4 T with ``p_i = T · p_j`` (fragment j into fragment i); a fragment's
``.info.txt`` pose A_k maps it into the scene, so ``T_ij = A_i⁻¹ A_j``.
"""
from __future__ import annotations

import dataclasses
import glob
import os
import re

import numpy as np

from sphere_jax.data.readers.io import (Cloud, DataError, atomic_write, check_exists,
                                        parse_numbers, read_points)


# |RᵀR − I| allowed in a gt.log: the 3DMatch release's own matrices reach 5.1e-4
# (redkitchen, 3DLoMatch); a shear or scale error is far larger.
RIGID_TOL = 1e-3


def _read_blocks(path, rows_per_block):
    """Blocks of one ``i j n`` line (integers) followed by ``rows_per_block`` matrix rows;
    a pair given twice is an error."""
    check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        lines = [(i + 1, ln) for i, ln in enumerate(f) if ln.strip()]
    if len(lines) % (rows_per_block + 1):
        raise DataError(path, f"{len(lines)} non-empty lines is not a whole number of "
                              f"{rows_per_block + 1}-line blocks (truncated?)")
    out, n_total, where = {}, None, {}
    for b in range(0, len(lines), rows_per_block + 1):
        no, head = lines[b]
        ids = parse_numbers(path, head, no)
        if len(ids) < 2:
            raise DataError(path, f"block header must be 'i j n', got {head.strip()!r}", no)
        if any(v != int(v) or v < 0 for v in ids[:3]):
            raise DataError(path, f"block header 'i j n' must hold non-negative integers, got "
                                  f"{head.strip()!r}", no)
        i, j = int(ids[0]), int(ids[1])
        if (i, j) in out:
            raise DataError(path, f"pair ({i}, {j}) given twice (first at line {where[i, j]})",
                            no)
        if len(ids) > 2:
            n_total = int(ids[2])
        rows = [parse_numbers(path, ln, n) for n, ln in lines[b + 1:b + 1 + rows_per_block]]
        width = len(rows[0])
        if any(len(r) != width for r in rows) or width != rows_per_block:
            raise DataError(path, f"matrix rows must have {rows_per_block} numbers", no + 1)
        out[(i, j)], where[(i, j)] = np.array(rows), no
    return out, n_total, where


def read_gt_log(path):
    """``{(i, j): T [4, 4]}`` with ``p_i = T p_j``, and the fragment count of the header. Each
    T must be rigid: RᵀR = I within :data:`RIGID_TOL`, det R positive, last row 0 0 0 1."""
    out, n_total, where = _read_blocks(path, 4)
    if not out:
        raise DataError(path, "holds no pair (an empty or header-only ground-truth log)")
    for pair, t in out.items():
        r = t[:3, :3]
        err = np.abs(r.T @ r - np.eye(3)).max()
        if err > RIGID_TOL or np.linalg.det(r) <= 0 or \
                np.abs(t[3] - [0, 0, 0, 1]).max() > 1e-6:
            raise DataError(path, f"pair {pair}: the matrix is not a rigid transform "
                                  f"(|RᵀR − I| = {err:.2g}, det R = {np.linalg.det(r):.4g}, "
                                  f"last row {t[3].tolist()})", where[pair] + 1)
    return out, n_total


def read_gt_info(path):
    """``{(i, j): information matrix [6, 6]}``."""
    return _read_blocks(path, 6)[0]


def read_gt_overlap(path):
    """``{(i, j): overlap ratio}`` from ``gt_overlap.log`` (rows ``i,j,ratio``)."""
    check_exists(path)
    out = {}
    with open(path, "r", encoding="ascii", errors="replace") as f:
        for no, ln in enumerate(f, 1):
            if ln.strip():
                v = parse_numbers(path, ln, no, 3)
                out[(int(v[0]), int(v[1]))] = v[2]
    return out


def format_matrix(m, end=""):
    """Text rows of a matrix as the benchmark files write them (tab-separated, 8 decimals)."""
    return ["\t".join(f"{v: .8e}" for v in row) + end for row in np.asarray(m)]


def write_pair_blocks(path, matrices: dict, n_fragments: int):
    """The gt.log / gt.info format: per pair ``(i, j)`` an ``i j n`` line, then the matrix."""
    lines = []
    for (i, j), m in sorted(matrices.items()):
        lines.append(f"{i}\t {j}\t {n_fragments}\t")
        lines.extend(format_matrix(m, "\t"))
    atomic_write(path, ("\n".join(lines) + "\n").encode())


def write_gt_log(path, transforms: dict, n_fragments: int):
    """Write ``{(i, j): T}`` in the gt.log format (``p_i = T p_j``)."""
    write_pair_blocks(path, transforms, n_fragments)


def write_gt_overlap(path, overlaps: dict):
    rows = [f"{i},{j},{r:.4f}" for (i, j), r in sorted(overlaps.items())]
    atomic_write(path, ("\n".join(rows) + "\n").encode())


def read_fragment_info(path):
    """``cloud_bin_K.info.txt``: ``(scene, sequence, first frame, last frame, pose A [4, 4])``,
    A mapping the fragment into the scene frame."""
    check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        lines = [ln for ln in f if ln.strip()]
    if len(lines) != 5:
        raise DataError(path, f"expected a header line and 4 pose rows, got {len(lines)} lines")
    head = lines[0].split()
    if len(head) != 4:
        raise DataError(path, "first line must be 'scene sequence first last'", 1)
    pose = np.array([parse_numbers(path, ln, k + 2, 4) for k, ln in enumerate(lines[1:])])
    return head[0], head[1], int(head[2]), int(head[3]), pose


def read_keypoint_indices(path, n_points=None):
    """A text file of point indices, one per line (3DMatch / 3DSmoothNet keypoints)."""
    check_exists(path)
    try:
        idx = np.loadtxt(path, dtype=np.int64, ndmin=1)
    except ValueError as e:
        raise DataError(path, f"keypoint indices must be integers ({e})") from None
    if idx.ndim != 1 or (len(idx) and idx.min() < 0) or (
            n_points is not None and len(idx) and idx.max() >= n_points):
        raise DataError(path, f"keypoint indices must be a column of integers in "
                              f"[0, {n_points})")
    return idx


@dataclasses.dataclass
class FragmentScene:
    """Fragments ``cloud_bin_K.ply`` of one scene and the ground truth of their pairs.

    ``pairs`` holds only pairs whose two fragments are present (a partial download, or this
    project's test subset, skips the rest). ``transforms[(i, j)]`` maps j into i.
    """
    name: str
    fragment_dir: str
    fragments: list
    transforms: dict
    overlaps: dict
    info: dict
    n_fragments: int | None
    skipped: tuple = ()          # ground-truth pairs whose clouds are missing

    @property
    def pairs(self):
        return sorted(self.transforms)

    def fragment_path(self, k):
        return os.path.join(self.fragment_dir, f"cloud_bin_{k}.ply")

    def cloud(self, k) -> Cloud:
        return read_points(self.fragment_path(k))

    def keypoints(self, k, pattern="cloud_bin_{k}_keypoints.txt"):
        return read_keypoint_indices(os.path.join(self.fragment_dir, pattern.format(k=k)))


def fragment_indices(fragment_dir) -> list[int]:
    """The sorted ``K`` of the ``cloud_bin_K.ply`` in a folder ([] when none, or no folder)."""
    names = (os.path.basename(p) for p in glob.glob(os.path.join(str(fragment_dir), "*.ply")))
    return sorted(int(m.group(1)) for m in (re.fullmatch(r"cloud_bin_(\d+)\.ply", n)
                                            for n in names) if m)


def load_fragment_scene(fragment_dir, gt_dir=None) -> FragmentScene:
    """A scene folder of ``cloud_bin_K.ply``; ground truth from ``gt_dir`` or, by the official
    layout, ``<fragment_dir>-evaluation/`` or the folder itself."""
    fragment_dir = os.path.normpath(str(fragment_dir))
    if not os.path.isdir(fragment_dir):
        raise DataError(fragment_dir, "no such scene folder")
    ks = fragment_indices(fragment_dir)
    if not ks:
        raise DataError(fragment_dir, "no cloud_bin_K.ply fragments")
    if gt_dir is None:
        gt_dir = next((d for d in (fragment_dir + "-evaluation", fragment_dir)
                       if os.path.isfile(os.path.join(d, "gt.log"))), None)
        if gt_dir is None:
            raise DataError(fragment_dir, "no gt.log here or in '<scene>-evaluation'; give "
                                          "gt_dir (evaluations: --config.data.gt=DIR)")
    log = os.path.join(gt_dir, "gt.log")
    transforms, n = read_gt_log(log)
    if not transforms:
        raise DataError(log, "no pairs: the ground truth is empty")
    present = set(ks)
    skipped = tuple(sorted(p for p in transforms if p[0] not in present or p[1] not in present))
    transforms = {p: t for p, t in transforms.items() if p not in skipped}
    if not transforms:
        raise DataError(log, f"none of its {len(skipped)} pairs has both clouds in "
                             f"{fragment_dir} (fragments there: {ks}); is it this scene's?")
    optional = lambda name, fn: fn(os.path.join(gt_dir, name)) if os.path.isfile(
        os.path.join(gt_dir, name)) else {}
    overlaps = optional("gt_overlap.log", read_gt_overlap)
    info = optional("gt.info", read_gt_info)
    return FragmentScene(os.path.basename(fragment_dir), fragment_dir, ks, transforms,
                         {p: overlaps[p] for p in transforms if p in overlaps},
                         {p: info[p] for p in transforms if p in info}, n, skipped)
