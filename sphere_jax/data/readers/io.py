"""Point-cloud and mesh files by suffix: PLY (:mod:`.ply`), PCD (:mod:`.pcd`), OFF, ModelNet
``.txt`` and ``.h5``, XYZ text and NumPy ``.npy``; the one import readers' users need.

Every reader validates what it reads and raises :class:`DataError` naming the file, the line
(for text formats) and what was wrong. Rows with non-finite coordinates are dropped (organised
scans mark missing returns that way); a file with no finite point is an error.
"""
from __future__ import annotations

import os
import re

import numpy as np

# Re-exported: io is where callers find every reader, the Cloud and the readers' error.
from sphere_jax.data.readers.cloud import (Cloud, DataError, atomic_write,  # noqa: F401
                                           check_exists, finite_cloud, parse_numbers,
                                           triangulate)
from sphere_jax.data.readers.pcd import read_pcd
from sphere_jax.data.readers.ply import read_ply, write_ply  # noqa: F401


SUFFIXES = (".ply", ".pcd", ".off", ".txt", ".xyz", ".npy")


def read_points(path) -> Cloud:
    """Read any supported point file by its suffix (:data:`SUFFIXES`)."""
    ext = os.path.splitext(str(path))[1].lower()
    readers = {".ply": read_ply, ".pcd": read_pcd, ".off": read_off, ".txt": read_txt,
               ".xyz": read_xyz, ".npy": read_npy}
    if os.path.isdir(str(path)):
        raise DataError(path, "is a folder: give one point file (a folder of scans is for "
                              "data.root or --data)")
    if ext not in readers:
        raise DataError(path, f"unknown point-cloud suffix {ext!r} (known: {sorted(readers)})")
    return readers[ext](path)


# ----------------------------------------------------------------------------------------------
# OFF meshes and ModelNet
# ----------------------------------------------------------------------------------------------

def read_off(path) -> Cloud:
    """OFF mesh (vertices and triangulated faces). Accepts the broken ModelNet header where
    the counts follow 'OFF' on the same line (``OFF490 518 0``)."""
    check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        lines = [ln.strip() for ln in f]
    rows = [(i + 1, ln) for i, ln in enumerate(lines) if ln and not ln.startswith("#")]
    if not rows or not rows[0][1].startswith("OFF"):
        raise DataError(path, "not an OFF file (no 'OFF' header)", 1)
    rest = rows[0][1][3:].split()
    body = rows[1:]
    if not rest:
        if not body:
            raise DataError(path, "missing counts line", 2)
        rest = body[0][1].split()
        body = body[1:]
    try:
        n_v, n_f = int(rest[0]), int(rest[1])
    except (ValueError, IndexError):
        raise DataError(path, f"bad counts {' '.join(rest)!r}", rows[0][0]) from None
    if n_v < 0 or n_f < 0:
        raise DataError(path, f"negative counts: {n_v} vertices, {n_f} faces", rows[0][0])
    if len(body) < n_v + n_f:
        raise DataError(path, f"truncated: {n_v} vertices + {n_f} faces announced, "
                              f"{len(body)} rows found", body[-1][0] if body else None)
    try:
        verts = np.array([ln.split()[:3] for _, ln in body[:n_v]], np.float64)
    except ValueError:
        bad = next(no for no, ln in body[:n_v] if len(ln.split()) < 3 or not _numeric(ln))
        raise DataError(path, "bad vertex row", bad) from None
    polys = []
    for no, ln in body[n_v:n_v + n_f]:
        tok = ln.split()
        try:
            k = int(tok[0])
            polys.append([int(t) for t in tok[1:1 + k]])
        except (ValueError, IndexError):
            raise DataError(path, f"bad face row {ln!r}", no) from None
        if len(polys[-1]) != k:
            raise DataError(path, f"face announces {k} vertices, has {len(polys[-1])}", no)
    return finite_cloud(path, verts, faces=triangulate(path, polys, n_v))


def _numeric(line):
    return all(re.fullmatch(r"[-+0-9.eE]+", t) for t in line.split()[:3])


def sample_mesh(cloud: Cloud, n: int, rng: np.random.Generator) -> Cloud:
    """``n`` points uniform on the surface of a triangle mesh (area-weighted), with the faces'
    normals."""
    if cloud.faces is None or len(cloud.faces) == 0:
        raise ValueError("sample_mesh needs a mesh with faces")
    v = cloud.points.astype(np.float64)[cloud.faces]                       # [F, 3, 3]
    cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    area = np.linalg.norm(cross, axis=1)
    if area.sum() <= 0:
        raise ValueError("mesh has zero surface area")
    tri = rng.choice(len(area), size=n, p=area / area.sum())
    u, w = rng.random(n), rng.random(n)
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    p = v[tri, 0] + u[:, None] * (v[tri, 1] - v[tri, 0]) + w[:, None] * (v[tri, 2] - v[tri, 0])
    normals = cross[tri] / np.maximum(area[tri], 1e-30)[:, None]
    return Cloud(p.astype(np.float32), normals.astype(np.float32))


def read_modelnet_txt(path) -> Cloud:
    """``modelnet40_normal_resampled`` shape: rows ``x,y,z,nx,ny,nz``."""
    check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        lines = [ln for ln in f.read().splitlines() if ln.strip()]
    if not lines:
        raise DataError(path, "empty file")
    try:
        arr = np.array(",".join(lines).replace(" ", "").split(","), np.float64)
    except ValueError:
        bad = next(i for i, ln in enumerate(lines) if not all(
            re.fullmatch(r"[-+0-9.eE]+", t.strip()) for t in ln.split(",")))
        raise DataError(path, f"non-numeric row {lines[bad]!r}", bad + 1) from None
    width = len(lines[0].split(","))
    if width not in (3, 6) or arr.size != width * len(lines):
        bad = next((i for i, ln in enumerate(lines) if len(ln.split(",")) != width), 0)
        raise DataError(path, f"expected 3 or 6 comma-separated values per row, all alike; "
                              f"got {len(lines[bad].split(','))}", bad + 1)
    arr = arr.reshape(len(lines), width)
    return finite_cloud(path, arr[:, :3], arr[:, 3:6] if width == 6 else None)


def read_modelnet_h5(path):
    """PointNet's ``ply_data_*.h5``: returns ``(points [B, N, 3] float32, labels [B] int64,
    normals or None)``. Needs h5py (``pip install h5py``)."""
    check_exists(path)
    try:
        import h5py
    except ImportError:
        raise ImportError("reading ModelNet .h5 files needs h5py: pip install h5py") from None
    try:
        with h5py.File(path, "r") as f:
            if "data" not in f or "label" not in f:
                raise DataError(path, f"expected datasets 'data' and 'label', found {list(f)}")
            data = np.asarray(f["data"], np.float32)
            labels = np.asarray(f["label"]).reshape(-1).astype(np.int64)
            normals = np.asarray(f["normal"], np.float32) if "normal" in f else None
    except OSError as e:
        raise DataError(path, f"not a readable HDF5 file ({e})") from None
    if data.ndim != 3 or data.shape[-1] != 3 or len(labels) != len(data):
        raise DataError(path, f"'data' must be [B, N, 3] with one label per shape, got "
                              f"{data.shape} and {labels.shape}")
    return data, labels, normals


# ----------------------------------------------------------------------------------------------
# XYZ text and NumPy arrays
# ----------------------------------------------------------------------------------------------

def read_txt(path) -> Cloud:
    """A ``.txt`` of comma-separated rows is a ModelNet shape (:func:`read_modelnet_txt`); of
    space-separated rows, an XYZ file (:func:`read_xyz`)."""
    check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        first = next((ln for ln in f if ln.strip()), "")
    return read_modelnet_txt(path) if "," in first else read_xyz(path)


def read_xyz(path) -> Cloud:
    """Rows ``x y z [more columns]`` (space or comma separated; ``#`` comments skipped): the
    first three columns are the points, the next three the normals when there are six."""
    check_exists(path)
    with open(path, "r", encoding="ascii", errors="replace") as f:
        rows = [(no, ln) for no, ln in enumerate(f, 1) if ln.strip() and
                not ln.lstrip().startswith("#")]
    if not rows:
        raise DataError(path, "empty file (no rows)")
    width = len(parse_numbers(path, rows[0][1], rows[0][0]))
    if width < 3:
        raise DataError(path, f"rows need at least 3 numbers (x y z), got {width}", rows[0][0])
    table = np.array([parse_numbers(path, ln, no, width) for no, ln in rows], np.float64)
    return finite_cloud(path, table[:, :3], table[:, 3:6] if width == 6 else None)


def read_npy(path) -> Cloud:
    """A NumPy ``.npy`` array ``[N, 3]`` (or ``[N, 6]``: points and normals)."""
    check_exists(path)
    try:
        a = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as e:
        raise DataError(path, f"not a readable .npy array ({e})") from None
    if a.ndim != 2 or a.shape[1] not in (3, 6) or a.dtype.kind not in "iuf":
        raise DataError(path, f"expected a numeric [N, 3] or [N, 6] array, got shape {a.shape} "
                              f"and dtype {a.dtype}")
    return finite_cloud(path, a[:, :3], a[:, 3:] if a.shape[1] == 6 else None)
