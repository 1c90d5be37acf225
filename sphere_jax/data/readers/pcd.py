"""PCL ``.pcd`` point clouds (DATA ascii or binary; binary_compressed through open3d)."""
from __future__ import annotations

import re

import numpy as np

from sphere_jax.data.readers.cloud import Cloud, DataError, check_exists, finite_cloud


_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4",
              ("I", 8): "i8", ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}


def read_pcd(path) -> Cloud:
    """PCL ``.pcd`` (DATA ascii or binary; binary_compressed through open3d): xyz, normals
    (``normal_x``...), packed ``rgb``/``rgba`` colours."""
    check_exists(path)
    with open(path, "rb") as f:
        raw = f.read()
    header, lines_of, pos, line_no = {}, {}, 0, 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise DataError(path, "header ends before DATA", line_no + 1)
        line = raw[pos:end].decode("ascii", "replace").strip()
        pos, line_no = end + 1, line_no + 1
        if not line or line.startswith("#"):
            continue
        key, *vals = line.split()
        header[key.upper()], lines_of[key.upper()] = vals, line_no
        if key.upper() == "DATA":
            break
    for key in ("FIELDS", "SIZE", "TYPE", "POINTS"):
        if key not in header:
            raise DataError(path, f"PCD header lacks {key}")
    def ints(key, default=None):
        vals = header.get(key, default)
        if not vals or not all(re.fullmatch(r"\d+", v) for v in vals):
            raise DataError(path, f"{key} must be non-negative integers, got "
                                  f"{' '.join(vals or [])!r}", lines_of.get(key))
        return [int(v) for v in vals]

    fields = header["FIELDS"]
    counts = ints("COUNT", ["1"] * len(fields))
    sizes = ints("SIZE")
    if not (len(fields) == len(sizes) == len(header["TYPE"]) == len(counts)):
        raise DataError(path, "FIELDS, SIZE, TYPE and COUNT have different lengths",
                        lines_of["FIELDS"])
    n = ints("POINTS")[0]
    if "WIDTH" in header and "HEIGHT" in header:
        w, h = ints("WIDTH")[0], ints("HEIGHT")[0]
        if w * h != n:
            raise DataError(path, f"WIDTH × HEIGHT = {w} × {h} is not POINTS {n}",
                            lines_of["POINTS"])
    mode = header["DATA"][0].lower() if header["DATA"] else ""
    try:
        types = [_PCD_TYPES[(t, sz)] for t, sz in zip(header["TYPE"], sizes)]
    except KeyError as e:
        raise DataError(path, f"unsupported PCD TYPE/SIZE {e}") from None
    if mode == "ascii":
        rows = [ln for ln in raw[pos:].split(b"\n") if ln.strip()]
        width = sum(counts)
        if len(rows) != n:
            raise DataError(path, f"POINTS says {n}, the data has {len(rows)} rows"
                                  + (" (truncated?)" if len(rows) < n else ""))
        try:
            table = np.array(b" ".join(rows).split(), np.float64)
        except ValueError:
            bad = next(k for k, r in enumerate(rows) if not _numbers(r))
            row = rows[bad].decode("ascii", "replace")
            raise DataError(path, f"non-numeric value in row {row!r}",
                            line_no + 1 + bad) from None
        if table.size != n * width:
            bad = next((k for k, r in enumerate(rows) if len(r.split()) != width), 0)
            raise DataError(path, f"expected {width} values per row, got "
                                  f"{len(rows[bad].split())}", line_no + 1 + bad)
        table = table.reshape(n, width)
        cols, start = {}, 0
        for name, c in zip(fields, counts):
            cols[name] = table[:, start] if c == 1 else table[:, start:start + c]
            start += c
        for name, t in zip(fields, types):
            if name in ("rgb", "rgba"):              # packed bytes: keep the bit pattern
                cols[name] = cols[name].astype(t)
    elif mode == "binary":
        dtype = np.dtype([(name, "<" + t, (c,)) if c > 1 else (name, "<" + t)
                          for name, t, c in zip(fields, types, counts)])
        if len(raw) - pos != n * dtype.itemsize:
            raise DataError(path, f"POINTS {n} × {dtype.itemsize} bytes = {n * dtype.itemsize} "
                                  f"bytes of data announced, {len(raw) - pos} found"
                            + (" (truncated?)" if len(raw) - pos < n * dtype.itemsize else ""))
        arr = np.frombuffer(raw, dtype, n, pos)
        cols = {name: arr[name] for name in fields}
    elif mode == "binary_compressed":
        # open3d decodes the LZF block, but returns uninitialised points from a block whose
        # sizes disagree with the header: check them first.
        row = sum(sz * c for sz, c in zip(sizes, counts))
        sizes_of_block = np.frombuffer(raw, "<u4", 2, pos) if len(raw) - pos >= 8 else None
        if sizes_of_block is None or int(sizes_of_block[1]) != n * row \
                or len(raw) - pos - 8 < int(sizes_of_block[0]):
            found = ("no block header" if sizes_of_block is None else
                     f"a block of {int(sizes_of_block[0])} compressed bytes for "
                     f"{int(sizes_of_block[1])}, {len(raw) - pos - 8} present")
            raise DataError(path, f"binary_compressed data must hold POINTS {n} × {row} = "
                                  f"{n * row} bytes; found {found} (truncated or corrupt?)")
        return _read_with_open3d(path)
    else:
        raise DataError(path, f"unknown PCD DATA mode {mode!r}")
    if not all(k in cols for k in "xyz"):
        raise DataError(path, "PCD has no x, y, z fields")
    points = np.stack([cols["x"], cols["y"], cols["z"]], 1)
    normals = np.stack([cols[k] for k in ("normal_x", "normal_y", "normal_z")], 1) if all(
        k in cols for k in ("normal_x", "normal_y", "normal_z")) else None
    colors = None
    key = "rgb" if "rgb" in cols else "rgba" if "rgba" in cols else None
    if key is not None:
        packed = np.ascontiguousarray(cols[key]).astype(np.float32).view(np.uint32) \
            if np.asarray(cols[key]).dtype.kind == "f" else np.asarray(cols[key], np.uint32)
        colors = np.stack([(packed >> 16) & 255, (packed >> 8) & 255, packed & 255], 1) / 255.0
    return finite_cloud(path, points, normals, colors)


def _numbers(row: bytes) -> bool:
    try:
        [float(t) for t in row.split()]
        return True
    except ValueError:
        return False


def _read_with_open3d(path) -> Cloud:
    import open3d as o3d
    pcd = o3d.io.read_point_cloud(str(path))
    if len(pcd.points) == 0:
        raise DataError(path, "open3d read no points (corrupt or unsupported file)")
    get = lambda has, arr: np.asarray(arr) if has else None
    return finite_cloud(path, np.asarray(pcd.points), get(pcd.has_normals(), pcd.normals),
                         get(pcd.has_colors(), pcd.colors))
