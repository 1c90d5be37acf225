"""What every reader shares: the :class:`Cloud` they return, their error
(:class:`~sphere_jax.checks.DataError`: file, line, what was wrong) and small helpers."""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from sphere_jax import files
from sphere_jax.checks import DataError  # noqa: F401  (the readers' error, re-exported)


@dataclasses.dataclass
class Cloud:
    """Points ``[N, 3]`` float32, with optional normals ``[N, 3]``, colours ``[N, 3]`` in [0, 1]
    (float32) and, for meshes, triangles ``[F, 3]`` int32. ``dropped``: rows of the file left
    out for non-finite coordinates (organised scans mark missing returns that way)."""
    points: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    faces: np.ndarray | None = None
    dropped: int = 0

    def __len__(self):
        return len(self.points)

    def select(self, idx):
        pick = lambda a: None if a is None else a[idx]
        return Cloud(self.points[idx], pick(self.normals), pick(self.colors))


def check_exists(path):
    if not os.path.isfile(path):
        raise DataError(path, "no such file")


def parse_numbers(path, line, no, count=None):
    """The numbers of text ``line`` (number ``no``) of ``path``, space or comma separated;
    :class:`DataError` naming the file and line when one is not a number or, with ``count``,
    when there are not ``count`` of them."""
    try:
        vals = [float(t) for t in line.replace(",", " ").split()]
    except ValueError:
        raise DataError(path, f"non-numeric row {line.strip()!r}", no) from None
    if count is not None and len(vals) != count:
        raise DataError(path, f"expected {count} numbers, got {len(vals)}", no)
    return vals


def finite_cloud(path, points, normals=None, colors=None, faces=None):
    points = np.asarray(points, np.float32)
    dropped = 0
    if faces is None:
        keep = np.all(np.isfinite(points), axis=1)
        dropped = int((~keep).sum())
        if dropped:
            points = points[keep]
            normals = None if normals is None else normals[keep]
            colors = None if colors is None else colors[keep]
    elif not np.all(np.isfinite(points)):
        raise DataError(path, "mesh has non-finite vertex coordinates")
    if len(points) == 0:
        raise DataError(path, "no finite points")
    as32 = lambda a: None if a is None else np.asarray(a, np.float32)
    return Cloud(points, as32(normals), as32(colors),
                 None if faces is None else np.asarray(faces, np.int32), dropped)


def triangulate(path, polys, n_vertices):
    """Faces (array ``[F, k]`` or list of lists) -> triangles ``[T, 3]`` by fanning."""
    tris = []
    if isinstance(polys, np.ndarray):
        polys = polys.tolist() if polys.shape[1] != 3 else polys
    if isinstance(polys, np.ndarray):
        tris = polys
    else:
        for p in polys:
            tris.extend([p[0], p[i], p[i + 1]] for i in range(1, len(p) - 1))
        tris = np.asarray(tris, np.int64).reshape(-1, 3)
    if tris.size and (tris.min() < 0 or tris.max() >= n_vertices):
        raise DataError(path, f"face indices outside [0, {n_vertices})")
    return tris


atomic_write = files.atomic_write          # the readers' writers use the one helper
