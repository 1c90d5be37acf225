"""Point-cloud and mesh files: PLY (ASCII / binary), PCD, OFF, ModelNet ``.txt`` and ``.h5``.

Every reader validates what it reads and raises :class:`DataError` naming the file, the line
(for text formats) and what was wrong. Rows with non-finite coordinates are dropped (organised
scans mark missing returns that way); a file with no finite point is an error.
"""
from __future__ import annotations

import dataclasses
import os
import re

import numpy as np

from sphere_jax.checks import DataError  # noqa: F401  (the readers' error, re-exported)


@dataclasses.dataclass
class Cloud:
    """Points ``[N, 3]`` float32, with optional normals ``[N, 3]``, colours ``[N, 3]`` in [0, 1]
    (float32) and, for meshes, triangles ``[F, 3]`` int32."""
    points: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    faces: np.ndarray | None = None

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


def _finite_cloud(path, points, normals=None, colors=None, faces=None):
    points = np.asarray(points, np.float32)
    if faces is None:
        keep = np.all(np.isfinite(points), axis=1)
        if not keep.all():
            points = points[keep]
            normals = None if normals is None else normals[keep]
            colors = None if colors is None else colors[keep]
    elif not np.all(np.isfinite(points)):
        raise DataError(path, "mesh has non-finite vertex coordinates")
    if len(points) == 0:
        raise DataError(path, "no finite points")
    as32 = lambda a: None if a is None else np.asarray(a, np.float32)
    return Cloud(points, as32(normals), as32(colors),
                 None if faces is None else np.asarray(faces, np.int32))


def read_points(path) -> Cloud:
    """Read any supported point file by its suffix (.ply, .pcd, .off, .txt, .xyz, .npy)."""
    ext = os.path.splitext(str(path))[1].lower()
    readers = {".ply": read_ply, ".pcd": read_pcd, ".off": read_off, ".txt": read_txt,
               ".xyz": read_xyz, ".npy": read_npy}
    if ext not in readers:
        raise DataError(path, f"unknown point-cloud suffix {ext!r} (known: {sorted(readers)})")
    return readers[ext](path)


# ----------------------------------------------------------------------------------------------
# PLY
# ----------------------------------------------------------------------------------------------

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
        faces = _triangulate(path, f[key], len(points))
    return _finite_cloud(path, points, normals, colors, faces)


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


def _triangulate(path, polys, n_vertices):
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


def atomic_write(path, data: bytes):
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


# ----------------------------------------------------------------------------------------------
# PCD
# ----------------------------------------------------------------------------------------------

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
            raise DataError(path, f"non-numeric value in row {rows[bad].decode('ascii', 'replace')!r}",
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
    return _finite_cloud(path, points, normals, colors)


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
    return _finite_cloud(path, np.asarray(pcd.points), get(pcd.has_normals(), pcd.normals),
                         get(pcd.has_colors(), pcd.colors))


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
    return _finite_cloud(path, verts, faces=_triangulate(path, polys, n_v))


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
    return _finite_cloud(path, arr[:, :3], arr[:, 3:6] if width == 6 else None)


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
        raise DataError(path, "no rows")
    width = len(parse_numbers(path, rows[0][1], rows[0][0]))
    if width < 3:
        raise DataError(path, f"rows need at least 3 numbers (x y z), got {width}", rows[0][0])
    table = np.array([parse_numbers(path, ln, no, width) for no, ln in rows], np.float64)
    return _finite_cloud(path, table[:, :3], table[:, 3:6] if width == 6 else None)


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
    return _finite_cloud(path, a[:, :3], a[:, 3:] if a.shape[1] == 6 else None)
