"""The Washington RGB-D Object dataset layout: reader, and a synthetic set written in it.

Layout (Lai et al. 2011): ``<root>/<category>/<category>_<instance>/`` holds, per frame,
``<stem>_crop.png`` (RGB), ``<stem>_depthcrop.png`` (uint16 mm), ``<stem>_maskcrop.png`` and
``<stem>_loc.txt`` (the crop's top-left pixel ``u,v`` in the 640×480 frame), with
``stem = <category>_<instance>_<video>_<frame>``. Videos 1, 2, 4 are turntable sequences at
about 30°, 45° and 60° elevation. A ``camera-intrinsics.txt`` at the root overrides the
dataset's Kinect intrinsics (fx = fy = 570.3, centre 320, 240).
"""
from __future__ import annotations

import dataclasses
import glob
import os
import re

import numpy as np

from sphere_jax.data import datasets
from sphere_jax.data.io import DataError, atomic_write

KINECT = np.array([[570.3, 0.0, 320.0], [0.0, 570.3, 240.0], [0.0, 0.0, 1.0]])
_STEM = re.compile(r"(.+)_(\d+)_(\d+)_(\d+)_crop\.png")


@dataclasses.dataclass
class Sample:
    """One cropped frame of one object instance (images are read on demand)."""
    category: str
    instance: str
    video: int
    frame: int
    stem: str                      # path without the _crop.png / _depthcrop.png suffix
    intrinsics: np.ndarray

    def color(self):
        return datasets._read_image(self.stem + "_crop.png")[..., :3]

    def mask(self):
        path = self.stem + "_maskcrop.png"
        if not os.path.isfile(path):                          # some releases lack masks
            return self.depth() > 0
        m = datasets._read_image(path)
        return (m[..., 0] if m.ndim == 3 else m) > 0

    def depth(self):
        d = datasets._read_image(self.stem + "_depthcrop.png")
        if d.dtype != np.uint16:
            raise DataError(self.stem + "_depthcrop.png", f"depth must be 16-bit, got {d.dtype}")
        return d

    def loc(self):
        path = self.stem + "_loc.txt"
        if not os.path.isfile(path):
            return 0, 0
        with open(path) as f:
            nums = re.findall(r"-?\d+", f.read())
        if len(nums) < 2:
            raise DataError(path, "expected 'u,v' of the crop's top-left pixel")
        return int(nums[0]), int(nums[1])

    def points(self, mask=None):
        """The object's points (camera frame, metres) from the masked depth crop (``mask``:
        :meth:`mask`, when the caller has read it already)."""
        mask = self.mask() if mask is None else mask
        depth = np.where(mask, self.depth(), 0).astype(np.uint16)
        return datasets.depth_to_cloud(depth, self.intrinsics, origin=self.loc()).points


def read_dataset(root, categories=None) -> list[Sample]:
    """Every cropped frame under ``root`` (sorted), optionally only some categories."""
    root = str(root)
    if not os.path.isdir(root):
        raise FileNotFoundError(f"Washington RGB-D root {root!r} is not a folder")
    k_file = os.path.join(root, "camera-intrinsics.txt")
    k = datasets.read_intrinsics(k_file) if os.path.isfile(k_file) else KINECT
    out = []
    for path in sorted(glob.glob(os.path.join(root, "*", "*", "*_crop.png"))):
        m = _STEM.fullmatch(os.path.basename(path))
        if not m:
            continue
        category = os.path.basename(os.path.dirname(os.path.dirname(path)))
        if categories and category not in categories:
            continue
        out.append(Sample(category, f"{m.group(1)}_{m.group(2)}", int(m.group(3)),
                          int(m.group(4)), path[:-len("_crop.png")], k))
    if not out:
        raise FileNotFoundError(f"no <category>/<instance>/*_crop.png frames under {root!r}")
    return out


# ----------------------------------------------------------------------------------------------
# Synthetic objects in this layout
# ----------------------------------------------------------------------------------------------

CATEGORIES = ["ball", "bottle", "bowl", "can", "cone", "mug", "ring", "blob", "cabinet", "lamp"]
VIDEOS = {1: 0.52, 2: 0.79, 4: 1.05}                         # elevation (rad) per video


def make_synthetic(out_dir, seed, instances=3, frames=6, camera=None, margin=4):
    """Each category × ``instances`` objects (own shape, size and colour around a category
    hue), filmed on a table by the virtual Kinect in the three videos × ``frames`` azimuths."""
    from sphere_jax.data import camera as cam
    from sphere_jax.data import shapes
    from sphere_jax.data.synthetic import write_png
    camera = camera or cam.Camera()
    rng = np.random.default_rng(seed)
    hues = {c: rng.uniform(0.15, 0.9, 3) for c in CATEGORIES}
    count = 0
    for category in CATEGORIES:
        for inst in range(1, instances + 1):
            size = rng.uniform(0.15, 0.25)
            mesh = shapes.make_object(category, rng).scale(size, (0, 0, 0))
            table = shapes.box(1.5, 1.5, 0.05, z=-0.05)
            albedo = np.clip(hues[category] + rng.normal(0, 0.08, 3), 0.05, 1.0)
            scene = cam.Scene([table, mesh], [[0.55, 0.5, 0.45], albedo])
            folder = os.path.join(out_dir, category, f"{category}_{inst}")
            os.makedirs(folder, exist_ok=True)
            for video, elev in VIDEOS.items():
                for f in range(1, frames + 1):
                    az = 2 * np.pi * (f - 1) / frames + rng.uniform(-0.1, 0.1)
                    dist = rng.uniform(0.7, 0.9)
                    eye = dist * np.array([np.cos(az) * np.cos(elev), np.sin(az) * np.cos(elev),
                                           np.sin(elev)])
                    pose = cam.look_at(eye, [0, 0, size * 0.4])
                    depth, color, ids = scene.render(camera, pose, rng)
                    sel = ids == 1
                    if sel.sum() < 30:
                        continue
                    vv, uu = np.nonzero(sel)
                    v0, v1 = max(vv.min() - margin, 0), min(vv.max() + margin, camera.height - 1)
                    u0, u1 = max(uu.min() - margin, 0), min(uu.max() + margin, camera.width - 1)
                    crop = (slice(v0, v1 + 1), slice(u0, u1 + 1))
                    stem = os.path.join(folder, f"{category}_{inst}_{video}_{f}")
                    write_png(stem + "_crop.png", color[crop])
                    write_png(stem + "_depthcrop.png",
                              np.round(depth[crop] * 1000).astype(np.uint16))
                    write_png(stem + "_maskcrop.png", (sel[crop] * 255).astype(np.uint8))
                    atomic_write(stem + "_loc.txt", f"{u0},{v0}\n".encode())
                    count += 1
    atomic_write(os.path.join(out_dir, "camera-intrinsics.txt"),
                 ("\n".join(datasets.format_matrix(camera.intrinsics)) + "\n").encode())
    return {"frames": count}
