"""PLY point clouds and meshes (ASCII and binary), read with the header checked against the
body (counts, byte order), and written as binary little-endian."""
from __future__ import annotations

import numpy as np

from sphere_jax.data.readers.cloud import (Cloud, DataError, atomic_write, check_exists,
                                           finite_cloud, triangulate)


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def _ply_header(path, f):
    first = f.readline()
    if first.strip() != b"ply":
        raise DataError(path, "not a PLY file (first line is not 'ply')", 1)
    fmt, elements, line_no = None, [], 1
    while True:
        raw = f.readline()
        line_no += 1
        if not raw:
            raise DataError(path, "header ends before 'end_header'", line_no)
        words = raw.decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            break
        if words[0] == "format":
            if len(words) < 2 or words[1] not in ("ascii", "binary_little_endian",
                                                  "binary_big_endian"):
                raise DataError(path, f"unknown PLY format {' '.join(words[1:])!r}", line_no)
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise DataError(path, f"bad element line {raw.strip()!r}", line_no)
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if not elements:
                raise DataError(path, "property before any element", line_no)
            if words[1] == "list" and len(words) == 5 and words[2] in _PLY_TYPES \
                    and words[3] in _PLY_TYPES:
                elements[-1][2].append((words[4], _PLY_TYPES[words[2]], _PLY_TYPES[words[3]]))
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]], None))
            else:
                raise DataError(path, f"bad property line {raw.strip()!r}", line_no)
        else:
            raise DataError(path, f"unexpected header line {raw.strip()!r}", line_no)
    if fmt is None:
        raise DataError(path, "PLY header has no 'format' line")
    return fmt, elements, line_no


def _ply_binary_element(path, buf, offset, count, props, endian):
    """Parse one binary element at ``offset``; returns (dict of arrays, new offset)."""
    if all(p[2] is None for p in props):
        dtype = np.dtype([(name, endian + t) for name, t, _ in props])
        end = offset + count * dtype.itemsize
        if end > len(buf):
            raise DataError(path, f"truncated: element needs {end} bytes, file has {len(buf)}")
        arr = np.frombuffer(buf, dtype, count, offset)
        return {name: arr[name] for name, _, _ in props}, end
    if len(props) == 1:
        # The common mesh case: one list property of constant length (triangles).
        name, count_t, item_t = props[0]
        if count == 0:
            return {name: np.zeros((0, 3), np.int64)}, offset
        if offset >= len(buf):
            raise DataError(path, "truncated: list element missing")
        k = int(np.frombuffer(buf, endian + count_t, 1, offset)[0])
        dtype = np.dtype([("n", endian + count_t), ("v", endian + item_t, (k,))])
        end = offset + count * dtype.itemsize
        if end <= len(buf):
            arr = np.frombuffer(buf, dtype, count, offset)
            if np.all(arr["n"] == k):
                return {name: arr["v"].astype(np.int64)}, end
    raise DataError(path, "binary PLY element with variable-length lists or mixed list and "
                          "scalar properties is not supported")


def read_ply(path) -> Cloud:
    """PLY point cloud or mesh: ``x y z`` (required), ``nx ny nz``, ``red green blue`` (uchar or
    float), faces from ``vertex_indices``/``vertex_index``. Other elements (e.g. the range
    grid of Stanford scans) are read past and ignored."""
    check_exists(path)
    with open(path, "rb") as f:
        fmt, elements, header_lines = _ply_header(path, f)
        body = f.read()
    data = {}
    if fmt == "ascii":
        lines = body.decode("ascii", "replace").splitlines()
        row = 0
        for name, count, props in elements:
            if row + count > len(lines):
                raise DataError(path, f"truncated: element '{name}' needs {count} lines, "
                                      f"{len(lines) - row} left", header_lines + len(lines))
            if name in ("vertex", "face"):
                data[name] = _ply_ascii_element(path, lines[row:row + count], props,
                                                header_lines + row + 1)
            row += count
        extra = [k for k in range(row, len(lines)) if lines[k].strip()]
        if extra:
            raise DataError(path, f"{len(extra)} row(s) after the last element the header "
                                  f"announces (its counts are wrong)", header_lines + extra[0] + 1)
    else:
        endian = "<" if fmt == "binary_little_endian" else ">"
        offset, complete = 0, True
        for name, count, props in elements:
            if "vertex" in data and ("face" in data or all(e[0] != "face" for e in elements)) \
                    and any(p[2] is not None for p in props):
                complete = False               # an unused list element (a range grid): skip
                break
            parsed, offset = _ply_binary_element(path, body, offset, count, props, endian)
            if name in ("vertex", "face"):
                data[name] = parsed
        if complete:
            _check_binary_size(path, body, offset, elements)
        if "vertex" in data:
            _check_endianness(path, data["vertex"], fmt)
    if "vertex" not in data:
        raise DataError(path, "PLY has no 'vertex' element")
    v = data["vertex"]
    missing = [c for c in "xyz" if c not in v]
    if missing:
        raise DataError(path, f"vertex element lacks properties {missing}")
    points = np.stack([v["x"], v["y"], v["z"]], 1)
    normals = np.stack([v["nx"], v["ny"], v["nz"]], 1) if all(
        k in v for k in ("nx", "ny", "nz")) else None
    colors = None
    if all(k in v for k in ("red", "green", "blue")):
        colors = np.stack([v["red"], v["green"], v["blue"]], 1).astype(np.float32)
        if v["red"].dtype.kind in "ui":
            colors /= 255.0
    faces = None
    if "face" in data:
        f = data["face"]
        key = "vertex_indices" if "vertex_indices" in f else "vertex_index"
        if key not in f:
            raise DataError(path, "face element lacks vertex_indices")
        faces = triangulate(path, f[key], len(points))
    return finite_cloud(path, points, normals, colors, faces)


def _check_binary_size(path, body, used, elements):
    """A body longer than its elements by a vertex or more means the header's counts are
    wrong (reading them would silently drop points); a few bytes (a final newline) pass."""
    vertex = next((e for e in elements if e[0] == "vertex"), None)
    record = sum(np.dtype(t).itemsize for _, t, _ in vertex[2]) if vertex else 1
    if len(body) - used >= record:
        counts = ", ".join(f"{n} {name}" for name, n, _ in elements)
        raise DataError(path, f"{len(body) - used} bytes after the elements the header "
                              f"announces ({counts}): its counts are wrong")


def _check_endianness(path, vertex, fmt):
    """Coordinates read in the wrong byte order are mostly absurd (1e38, 1e-40); if the other
    order gives sane ones, the header's format is wrong."""
    xyz = [vertex[c] for c in "xyz" if c in vertex]
    if not xyz or xyz[0].dtype.kind != "f" or len(xyz[0]) == 0:
        return
    a = np.stack(xyz, 1).astype(xyz[0].dtype.newbyteorder("="))      # values, native order

    def sane(v):                 # over the finite values: organised scans mark holes NaN
        with np.errstate(all="ignore"):
            mag = np.abs(v[np.isfinite(v)].astype(np.float64))
            return float(np.mean((mag == 0) | ((mag > 1e-20) & (mag < 1e9)))) if mag.size else 0.0

    if sane(a) < 0.9:
        other = sane(a.byteswap())                   # the bytes read in the other order
        if other > 0.99:
            raise DataError(path, f"the header says {fmt}, but the coordinates read that way "
                                  f"are absurd (|x| up to {np.nanmax(np.abs(a)):.3g}) and read "
                                  f"in the other byte order are not: the format line is wrong")
        raise DataError(path, f"{100 * (1 - sane(a)):.0f} % of the coordinates are absurd "
                              f"(|x| up to {np.nanmax(np.abs(a)):.3g}): corrupt data")


def _ply_ascii_element(path, lines, props, first_line):
    if all(p[2] is None for p in props):
        try:
            arr = np.array(" ".join(lines).split(), np.float64)
        except ValueError as e:
            raise DataError(path, f"non-numeric value in data ({e})", first_line) from None
        if arr.size != len(lines) * len(props):
            bad = next((i for i, ln in enumerate(lines) if len(ln.split()) != len(props)), 0)
            raise DataError(path, f"expected {len(props)} values per row, got "
                                  f"{len(lines[bad].split())}", first_line + bad)
        arr = arr.reshape(len(lines), len(props))
        return {name: arr[:, i].astype(t) for i, (name, t, _) in enumerate(props)}
    if len(props) != 1:
        raise DataError(path, "ASCII element mixing list and scalar properties is not supported")
    rows = []
    for i, ln in enumerate(lines):
        tok = ln.split()
        try:
            n = int(tok[0])
            vals = [int(t) for t in tok[1:1 + n]]
        except (ValueError, IndexError):
            raise DataError(path, f"bad list row {ln!r}", first_line + i) from None
        if len(vals) != n:
            raise DataError(path, f"list row announces {n} values, has {len(vals)}",
                            first_line + i)
        rows.append(vals)
    return {props[0][0]: rows}


def write_ply(path, points, normals=None, colors=None):
    """Binary little-endian PLY with float xyz, optional float normals and uchar colours."""
    points = np.asarray(points, np.float32)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(points)}",
              "property float x", "property float y", "property float z"]
    if normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
        header += ["property float nx", "property float ny", "property float nz"]
    if colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    arr = np.empty(len(points), fields)
    arr["x"], arr["y"], arr["z"] = points.T
    if normals is not None:
        arr["nx"], arr["ny"], arr["nz"] = np.asarray(normals, np.float32).T
    if colors is not None:
        c = np.clip(np.round(np.asarray(colors) * 255), 0, 255).astype(np.uint8)
        arr["red"], arr["green"], arr["blue"] = c.T
    atomic_write(path, ("\n".join(header + ["end_header"]) + "\n").encode() + arr.tobytes())
