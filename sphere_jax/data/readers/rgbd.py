"""RGB-D frames: camera intrinsics, poses, images, back-projection to coloured clouds, and the
labelled object frames of the synthetic table tops.

Pinhole convention: x right, y down, z forward; poses are camera-to-world (CONVENTIONS.md §6,
also open3d's ``trajectory.log``).
"""
from __future__ import annotations

import dataclasses
import glob
import json
import os

import numpy as np

from sphere_jax import files
from sphere_jax.data.readers import threedmatch
from sphere_jax.data.readers.io import Cloud, DataError, check_exists, parse_numbers


def read_intrinsics(path):
    """3×3 camera matrix from a text file (3 rows) or an open3d JSON (``intrinsic_matrix``,
    column-major)."""
    check_exists(path)
    if str(path).endswith(".json"):
        with open(path) as f:
            try:
                k = np.array(json.load(f)["intrinsic_matrix"], np.float64).reshape(3, 3).T
            except (ValueError, KeyError) as e:
                raise DataError(path, f"expected an 'intrinsic_matrix' of 9 numbers ({e})")
        return k
    return _read_square(path, 3)


def read_pose(path):
    """A 4×4 matrix from a text file (camera-to-world for RGB-D frames)."""
    check_exists(path)
    return _read_square(path, 4)


def _read_square(path, n):
    with open(path) as f:
        rows = [parse_numbers(path, ln, no, n) for no, ln in enumerate(f, 1) if ln.strip()]
    if len(rows) != n:
        raise DataError(path, f"expected {n} rows of {n} numbers, got {len(rows)} rows")
    return np.array(rows)


def read_image(path):
    """An image file as an array (open3d decodes PNG / JPG, 16-bit depth included)."""
    import open3d as o3d      # only here: the readers above need no open3d
    check_exists(path)
    img = np.asarray(o3d.io.read_image(str(path)))
    if img.size == 0:
        raise DataError(path, "could not decode the image")
    return img


def write_png(path, array):
    """Write an image array (uint8 colour or mask, uint16 depth) as PNG, atomically."""
    import open3d as o3d
    with files.replacing(path, ".png") as tmp:
        if not o3d.io.write_image(tmp, o3d.geometry.Image(np.ascontiguousarray(array))):
            raise OSError(f"could not write {path}")


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
    depth = read_image(depth_path)
    if depth.dtype != np.uint16:
        raise DataError(depth_path, f"depth must be a 16-bit image, got {depth.dtype}")
    color = read_image(color_path) if color_path is not None else None
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
    """Every ``frame-N`` of a folder written by
    :func:`sphere_jax.data.generators.synthetic.make_object_frames`
    (``.color.png``, ``.depth.png``, ``.mask.png``, ``.pose.txt``, ``.labels.json``)."""
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
        out.append(ObjectFrame(os.path.basename(s), read_image(s + ".color.png")[..., :3],
                               read_image(s + ".depth.png"), read_image(s + ".mask.png"),
                               read_pose(s + ".pose.txt"), k, labels))
    return out


@dataclasses.dataclass
class FrameSequence:
    """A posed RGB-D sequence: per frame ``color`` / ``depth`` image paths and the 4×4
    camera-to-world ``poses [F, 4, 4]``, with the pinhole ``intrinsics``."""
    folder: str
    color: list
    depth: list
    poses: np.ndarray
    intrinsics: np.ndarray

    def __len__(self):
        return len(self.depth)


TRAJECTORY = "trajectory.log"      # open3d's layout: camera-to-world poses, one per frame


def _toolbox_stems(folder):
    """``folder/frame-N`` for each depth frame of the 3DMatch toolbox layout, sorted."""
    return sorted(p[:-len(".depth.png")]
                  for p in glob.glob(os.path.join(folder, "frame-*.depth.png")))


def is_frame_sequence(folder) -> bool:
    """A posed RGB-D sequence in the 3DMatch toolbox layout or open3d's."""
    folder = str(folder)
    return bool(_toolbox_stems(folder)) or (
        os.path.isfile(os.path.join(folder, TRAJECTORY))
        and bool(glob.glob(os.path.join(folder, "depth", "*.png"))))


def _beside(folder, patterns, what):
    """The one file matching ``patterns`` in ``folder`` or else its parent."""
    for where in (folder, os.path.dirname(os.path.abspath(folder))):
        found = sorted({p for pat in patterns for p in glob.glob(os.path.join(where, pat))})
        if len(found) > 1:
            raise DataError(where, f"{len(found)} candidate {what} files "
                                   f"({', '.join(map(os.path.basename, found))}); keep one")
        if found:
            return found[0]
    raise DataError(folder, f"no {what} ({' or '.join(patterns)}) in the folder or its parent")


def _read_open3d_sequence(folder) -> FrameSequence:
    """open3d's layout: ``depth/*.png`` and ``color/*`` (sorted by name), ``trajectory.log``
    (a camera-to-world pose per frame, in gt.log's block format, in file order) and the
    intrinsics as an open3d JSON (``camera*.json``) in the folder or its parent."""
    depth = sorted(glob.glob(os.path.join(folder, "depth", "*.png")))
    color = sorted(p for ext in ("png", "jpg")
                   for p in glob.glob(os.path.join(folder, "color", f"*.{ext}")))
    poses, _ = threedmatch.read_gt_log(os.path.join(folder, TRAJECTORY))
    if len(poses) != len(depth):
        raise DataError(os.path.join(folder, TRAJECTORY),
                        f"{len(poses)} poses for {len(depth)} depth images in depth/")
    if color and len(color) != len(depth):
        raise DataError(os.path.join(folder, "color"),
                        f"{len(color)} colour images for {len(depth)} depth images")
    intrinsics = read_intrinsics(_beside(folder, ("camera*.json",), "camera intrinsics"))
    return FrameSequence(folder, color or [None] * len(depth), depth,
                         np.stack(list(poses.values())), intrinsics)


def read_frame_sequence(folder) -> FrameSequence:
    """A posed RGB-D sequence: the 3DMatch toolbox layout (``frame-N.{color,depth}.png`` and
    ``frame-N.pose.txt``, with ``camera-intrinsics.txt`` in the folder or its parent) or
    open3d's (``depth/``, ``color/``, ``trajectory.log``, ``camera*.json``)."""
    folder = str(folder)
    stems = _toolbox_stems(folder)
    if not stems and is_frame_sequence(folder):
        return _read_open3d_sequence(folder)
    if not stems:
        raise DataError(folder, "no frame-N.depth.png frames")
    k_path = _beside(folder, ("camera-intrinsics.txt",), "camera intrinsics")
    color = [s + ".color.png" if os.path.isfile(s + ".color.png") else None for s in stems]
    return FrameSequence(folder, color, [s + ".depth.png" for s in stems],
                         np.stack([read_pose(s + ".pose.txt") for s in stems]),
                         read_intrinsics(k_path))
