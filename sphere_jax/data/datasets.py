"""Benchmark layouts: 3DMatch-style fragment scenes, Stanford ``.conf`` scans, RGB-D frames.

Ground-truth directions (checked on the real files in ``../shared/data`` by the tests):

* ``gt.log`` entry ``(i, j)`` is a 4×4 T with ``p_i = T · p_j`` (fragment j into fragment i);
  a fragment's ``.info.txt`` pose A_k maps it into the scene, so ``T_ij = A_i⁻¹ A_j``.
* Stanford ``.conf``: ``bmesh FILE tx ty tz qx qy qz qw`` means ``p_world = R(q)ᵀ p + t``.
* RGB-D ``frame-N.pose.txt`` (and open3d's ``trajectory.log``) are camera-to-world.
"""
from __future__ import annotations

import dataclasses
import glob
import os
import re

import numpy as np

from sphere_jax.data.io import Cloud, DataError, atomic_write, _check_exists, read_points


# ----------------------------------------------------------------------------------------------
# gt.log / gt.info / gt_overlap.log
# ----------------------------------------------------------------------------------------------

def _numbers(path, line, no, count=None):
    try:
        vals = [float(t) for t in line.replace(",", " ").split()]
    except ValueError:
        raise DataError(path, f"non-numeric row {line.strip()!r}", no) from None
    if count is not None and len(vals) != count:
        raise DataError(path, f"expected {count} numbers, got {len(vals)}", no)
    return vals


def _read_blocks(path, rows_per_block):
    """Blocks of one ``i j n`` line followed by ``rows_per_block`` matrix rows."""
    _check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        lines = [(i + 1, ln) for i, ln in enumerate(f) if ln.strip()]
    if len(lines) % (rows_per_block + 1):
        raise DataError(path, f"{len(lines)} non-empty lines is not a whole number of "
                              f"{rows_per_block + 1}-line blocks (truncated?)")
    out, n_total = {}, None
    for b in range(0, len(lines), rows_per_block + 1):
        no, head = lines[b]
        ids = _numbers(path, head, no)
        if len(ids) < 2:
            raise DataError(path, f"block header must be 'i j n', got {head.strip()!r}", no)
        i, j = int(ids[0]), int(ids[1])
        if len(ids) > 2:
            n_total = int(ids[2])
        rows = [_numbers(path, ln, n) for n, ln in lines[b + 1:b + 1 + rows_per_block]]
        width = len(rows[0])
        if any(len(r) != width for r in rows) or width != rows_per_block:
            raise DataError(path, f"matrix rows must have {rows_per_block} numbers", no + 1)
        out[(i, j)] = np.array(rows)
    return out, n_total


def read_gt_log(path):
    """``{(i, j): T [4, 4]}`` with ``p_i = T p_j``, and the fragment count of the header."""
    return _read_blocks(path, 4)


def read_gt_info(path):
    """``{(i, j): information matrix [6, 6]}``."""
    return _read_blocks(path, 6)[0]


def read_gt_overlap(path):
    """``{(i, j): overlap ratio}`` from ``gt_overlap.log`` (rows ``i,j,ratio``)."""
    _check_exists(path)
    out = {}
    with open(path, "r", encoding="ascii", errors="replace") as f:
        for no, ln in enumerate(f, 1):
            if ln.strip():
                v = _numbers(path, ln, no, 3)
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
    _check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        lines = [ln for ln in f if ln.strip()]
    if len(lines) != 5:
        raise DataError(path, f"expected a header line and 4 pose rows, got {len(lines)} lines")
    head = lines[0].split()
    if len(head) != 4:
        raise DataError(path, "first line must be 'scene sequence first last'", 1)
    pose = np.array([_numbers(path, ln, k + 2, 4) for k, ln in enumerate(lines[1:])])
    return head[0], head[1], int(head[2]), int(head[3]), pose


def read_keypoint_indices(path, n_points=None):
    """A text file of point indices, one per line (3DMatch / 3DSmoothNet keypoints)."""
    _check_exists(path)
    try:
        idx = np.loadtxt(path, dtype=np.int64, ndmin=1)
    except ValueError as e:
        raise DataError(path, f"keypoint indices must be integers ({e})") from None
    if idx.ndim != 1 or (len(idx) and idx.min() < 0) or (
            n_points is not None and len(idx) and idx.max() >= n_points):
        raise DataError(path, f"keypoint indices must be a column of integers in "
                              f"[0, {n_points})")
    return idx


# ----------------------------------------------------------------------------------------------
# A scene of fragments in the 3DMatch layout
# ----------------------------------------------------------------------------------------------

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


def load_fragment_scene(fragment_dir, gt_dir=None) -> FragmentScene:
    """A scene folder of ``cloud_bin_K.ply``; ground truth from ``gt_dir`` or, by the official
    layout, ``<fragment_dir>-evaluation/`` or the folder itself."""
    fragment_dir = os.path.normpath(str(fragment_dir))
    if not os.path.isdir(fragment_dir):
        raise DataError(fragment_dir, "no such scene folder")
    ks = sorted(int(m.group(1)) for m in (re.fullmatch(r"cloud_bin_(\d+)\.ply",
                                                          os.path.basename(p))
                                          for p in glob.glob(os.path.join(fragment_dir, "*.ply")))
                if m)
    if not ks:
        raise DataError(fragment_dir, "no cloud_bin_K.ply fragments")
    if gt_dir is None:
        gt_dir = next((d for d in (fragment_dir + "-evaluation", fragment_dir)
                       if os.path.isfile(os.path.join(d, "gt.log"))), None)
        if gt_dir is None:
            raise DataError(fragment_dir, "no gt.log here or in '<scene>-evaluation'; pass "
                                          "gt_dir")
    transforms, n = read_gt_log(os.path.join(gt_dir, "gt.log"))
    present = set(ks)
    skipped = tuple(sorted(p for p in transforms if p[0] not in present or p[1] not in present))
    transforms = {p: t for p, t in transforms.items() if p not in skipped}
    optional = lambda name, fn: fn(os.path.join(gt_dir, name)) if os.path.isfile(
        os.path.join(gt_dir, name)) else {}
    overlaps = optional("gt_overlap.log", read_gt_overlap)
    info = optional("gt.info", read_gt_info)
    return FragmentScene(os.path.basename(fragment_dir), fragment_dir, ks, transforms,
                         {p: overlaps[p] for p in transforms if p in overlaps},
                         {p: info[p] for p in transforms if p in info}, n, skipped)


# ----------------------------------------------------------------------------------------------
# Stanford scans
# ----------------------------------------------------------------------------------------------

def quaternion_to_matrix(q_xyzw):
    x, y, z, w = np.asarray(q_xyzw, np.float64) / np.linalg.norm(q_xyzw)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_stanford_conf(path):
    """``{scan file name: T [4, 4]}`` mapping each scan into the world: ``p_world = R(q)ᵀ p + t``."""
    _check_exists(path)
    out = {}
    with open(path, "r", encoding="ascii", errors="replace") as f:
        for no, ln in enumerate(f, 1):
            tok = ln.split()
            if not tok or tok[0] != "bmesh":
                continue
            if len(tok) != 9:
                raise DataError(path, "bmesh line must be 'bmesh FILE tx ty tz qx qy qz qw'", no)
            v = _numbers(path, " ".join(tok[2:]), no, 7)
            t = np.eye(4)
            t[:3, :3] = quaternion_to_matrix(v[3:]).T
            t[:3, 3] = v[:3]
            out[tok[1]] = t
    if not out:
        raise DataError(path, "no 'bmesh' lines")
    return out


@dataclasses.dataclass
class ScanSet:
    """Scans with world poses (``p_world = poses[name] · p``); pairs in the gt.log direction:
    ``transform(i, j)`` maps scan j into scan i."""
    folder: str
    poses: dict

    @property
    def names(self):
        return list(self.poses)

    def cloud(self, name) -> Cloud:
        return read_points(os.path.join(self.folder, name))

    def transform(self, i, j):
        return np.linalg.inv(self.poses[i]) @ self.poses[j]


def load_stanford_scans(conf_path) -> ScanSet:
    """The scans listed in a Stanford ``.conf`` (they sit beside it)."""
    return ScanSet(os.path.dirname(str(conf_path)), read_stanford_conf(conf_path))


# ----------------------------------------------------------------------------------------------
# RGB-D frames
# ----------------------------------------------------------------------------------------------

def read_intrinsics(path):
    """3×3 camera matrix from a text file (3 rows) or an open3d JSON (``intrinsic_matrix``,
    column-major)."""
    _check_exists(path)
    if str(path).endswith(".json"):
        import json
        with open(path) as f:
            try:
                k = np.array(json.load(f)["intrinsic_matrix"], np.float64).reshape(3, 3).T
            except (ValueError, KeyError) as e:
                raise DataError(path, f"expected an 'intrinsic_matrix' of 9 numbers ({e})")
        return k
    return _read_square(path, 3)


def read_pose(path):
    """A 4×4 matrix from a text file (camera-to-world for RGB-D frames)."""
    _check_exists(path)
    return _read_square(path, 4)


def _read_square(path, n):
    with open(path) as f:
        rows = [_numbers(path, ln, no, n) for no, ln in enumerate(f, 1) if ln.strip()]
    if len(rows) != n:
        raise DataError(path, f"expected {n} rows of {n} numbers, got {len(rows)} rows")
    return np.array(rows)


def _read_image(path):
    import open3d as o3d
    _check_exists(path)
    img = np.asarray(o3d.io.read_image(str(path)))
    if img.size == 0:
        raise DataError(path, "could not decode the image")
    return img


def depth_to_cloud(depth, intrinsics, color=None, pose=None, depth_scale=1000.0,
                   depth_trunc=np.inf, origin=(0, 0)) -> Cloud:
    """Back-project a depth image ``[H, W]`` (raw units / ``depth_scale`` = metres) through
    the pinhole ``intrinsics``; zero depth is a missing return. With ``pose`` (camera-to-world)
    the points are in world coordinates; ``color`` ``[H, W, 3]`` gives per-point colours.
    A crop passes ``origin = (u0, v0)``, its top-left pixel in the image of the intrinsics."""
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise ValueError(f"depth must be [H, W], got {depth.shape}")
    z = depth.astype(np.float64) / depth_scale
    v, u = np.nonzero((z > 0) & (z < depth_trunc))
    z = z[v, u]
    k = np.asarray(intrinsics, np.float64)
    x = (u + origin[0] - k[0, 2]) * z / k[0, 0]
    y = (v + origin[1] - k[1, 2]) * z / k[1, 1]
    pts = np.stack([x, y, z], 1)
    if pose is not None:
        pose = np.asarray(pose, np.float64)
        pts = pts @ pose[:3, :3].T + pose[:3, 3]
    colors = None
    if color is not None:
        color = np.asarray(color)
        if color.shape[:2] != depth.shape:
            raise ValueError(f"color {color.shape[:2]} and depth {depth.shape} differ in size")
        colors = color[v, u, :3].astype(np.float32) / (255.0 if color.dtype == np.uint8 else 1.0)
    if len(pts) == 0:
        raise ValueError("depth image has no valid pixel")
    return Cloud(pts.astype(np.float32), colors=colors)


def read_rgbd_frame(color_path, depth_path, intrinsics, pose=None, depth_scale=1000.0,
                    depth_trunc=np.inf) -> Cloud:
    """Colour + depth image files -> coloured point cloud (world frame if ``pose`` given)."""
    depth = _read_image(depth_path)
    if depth.dtype != np.uint16:
        raise DataError(depth_path, f"depth must be a 16-bit image, got {depth.dtype}")
    color = _read_image(color_path) if color_path is not None else None
    return depth_to_cloud(depth, intrinsics, color, pose, depth_scale, depth_trunc)


@dataclasses.dataclass
class ObjectFrame:
    """A labelled RGB-D frame of objects (the synthetic table-top layout): ``color [H, W, 3]``,
    ``depth [H, W]`` uint16 mm, ``mask [H, W]`` instance ids, camera-to-world ``pose``, and
    ``instances``: dicts with ``id``, ``category``, ``box [u0, v0, u1, v1]`` and the 4×4
    object-to-world ``pose`` (rotation × scale, translation)."""
    name: str
    color: np.ndarray
    depth: np.ndarray
    mask: np.ndarray
    pose: np.ndarray
    intrinsics: np.ndarray
    instances: list

    def points(self, depth_scale=1000.0):
        """``(points [M, 3] camera frame, pixels [M, 2] as (v, u))`` of the valid depth."""
        v, u = np.nonzero(self.depth > 0)
        cloud = depth_to_cloud(self.depth, self.intrinsics, depth_scale=depth_scale)
        return cloud.points, np.stack([v, u], 1)


def read_object_frames(folder) -> list[ObjectFrame]:
    """Every ``frame-N`` of a folder written by :func:`sphere_jax.data.synthetic.make_object_frames`
    (``.color.png``, ``.depth.png``, ``.mask.png``, ``.pose.txt``, ``.labels.json``)."""
    import json
    folder = str(folder)
    k = read_intrinsics(os.path.join(folder, "camera-intrinsics.txt"))
    stems = sorted(p[:-len(".labels.json")]
                   for p in glob.glob(os.path.join(folder, "frame-*.labels.json")))
    if not stems:
        raise DataError(folder, "no frame-N.labels.json object frames")
    out = []
    for s in stems:
        with open(s + ".labels.json") as f:
            try:
                labels = json.load(f)["instances"]
            except (ValueError, KeyError) as e:
                raise DataError(s + ".labels.json", f"expected {{'instances': [...]}} ({e})")
        out.append(ObjectFrame(os.path.basename(s), _read_image(s + ".color.png")[..., :3],
                               _read_image(s + ".depth.png"), _read_image(s + ".mask.png"),
                               read_pose(s + ".pose.txt"), k, labels))
    return out
