"""The Washington RGB-D Object dataset layout (reader; :mod:`sphere_jax.data.generators.washington`
writes a synthetic set in it).

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

from sphere_jax import checks
from sphere_jax.data.readers import rgbd
from sphere_jax.data.readers.io import DataError

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
        return rgbd.read_image(self.stem + "_crop.png")[..., :3]

    def mask(self):
        path = self.stem + "_maskcrop.png"
        if not os.path.isfile(path):                          # some releases lack masks
            return self.depth() > 0
        m = rgbd.read_image(path)
        return (m[..., 0] if m.ndim == 3 else m) > 0

    def depth(self):
        d = rgbd.read_image(self.stem + "_depthcrop.png")
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
        return rgbd.depth_to_cloud(depth, self.intrinsics, origin=self.loc()).points


def read_dataset(root, categories=None) -> list[Sample]:
    """Every cropped frame under ``root`` (sorted), optionally only some categories."""
    root = str(root)
    if not os.path.isdir(root):
        raise checks.MissingError(f"Washington RGB-D root {root!r} is not a folder")
    k_file = os.path.join(root, "camera-intrinsics.txt")
    k = rgbd.read_intrinsics(k_file) if os.path.isfile(k_file) else KINECT
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
        raise checks.MissingError(f"no <category>/<instance>/*_crop.png frames under {root!r}")
    return out
