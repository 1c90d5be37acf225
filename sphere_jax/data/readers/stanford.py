"""Stanford 3D Scanning Repository range scans and their ``.conf`` poses.

``bmesh FILE tx ty tz qx qy qz qw`` means ``p_world = R(q)ᵀ p + t`` (CONVENTIONS.md §6: the
conjugate quaternion; R(q) itself does not align the scans).
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from sphere_jax.data.readers.io import Cloud, DataError, check_exists, parse_numbers, read_points


def quaternion_to_matrix(q_xyzw):
    x, y, z, w = np.asarray(q_xyzw, np.float64) / np.linalg.norm(q_xyzw)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_stanford_conf(path):
    """``{scan file name: T [4, 4]}`` mapping each scan into the world:
    ``p_world = R(q)ᵀ p + t``."""
    check_exists(path)
    out = {}
    with open(path, "r", encoding="ascii", errors="replace") as f:
        for no, ln in enumerate(f, 1):
            tok = ln.split()
            if not tok or tok[0] != "bmesh":
                continue
            if len(tok) != 9:
                raise DataError(path, "bmesh line must be 'bmesh FILE tx ty tz qx qy qz qw'", no)
            v = parse_numbers(path, " ".join(tok[2:]), no, 7)
            if not np.linalg.norm(v[3:]) > 1e-8:
                raise DataError(path, f"the quaternion of {tok[1]} is zero (no rotation)", no)
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
