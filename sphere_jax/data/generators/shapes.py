"""Procedural meshes: the object classes of the synthetic data (canonical pose: z up, resting
on z = 0, centred in x/y, about 1 unit tall) and the building blocks of synthetic rooms.

Every builder takes a ``numpy.random.Generator`` and varies proportions, so instances of a
class differ while staying recognisable. Meshes are open3d ``TriangleMesh`` (legacy).
"""
from __future__ import annotations

import numpy as np
import open3d as o3d

from sphere_jax.data.readers.io import Cloud, sample_mesh

M = o3d.geometry.TriangleMesh


def _merge(parts):
    out = M()
    for p in parts:
        out += p
    return out


def _at(mesh, x=0.0, y=0.0, z=0.0):
    return mesh.translate((x, y, z))


def box(w, d, h, x=0.0, y=0.0, z=0.0):
    """Axis-aligned box of size (w, d, h) with its bottom face centred at (x, y, z)."""
    return _at(M.create_box(w, d, h), x - w / 2, y - d / 2, z)


def cylinder(r, h, x=0.0, y=0.0, z=0.0, resolution=24):
    """Vertical cylinder standing on (x, y, z)."""
    return _at(M.create_cylinder(r, h, resolution=resolution), x, y, z + h / 2)


def smooth_blob(rng, radius=0.5, amplitude=0.25, resolution=20):
    """A random smooth closed surface: a sphere displaced radially by a few low-frequency
    harmonics (the 'random smooth mesh')."""
    mesh = M.create_sphere(1.0, resolution=resolution)
    v = np.asarray(mesh.vertices)
    disp = np.zeros(len(v))
    for _ in range(4):
        k = rng.normal(size=3) * rng.uniform(1.0, 3.0)
        disp += rng.normal() * np.sin(v @ k + rng.uniform(0, 2 * np.pi))
    disp = amplitude * disp / max(np.abs(disp).max(), 1e-9)
    mesh.vertices = o3d.utility.Vector3dVector(v * radius * (1.0 + disp)[:, None])
    return mesh


# ----------------------------------------------------------------------------------------------
# Object classes (canonical pose)
# ----------------------------------------------------------------------------------------------

def _cabinet(rng):
    return box(rng.uniform(0.5, 0.9), rng.uniform(0.35, 0.6), 1.0)


def _can(rng):
    return cylinder(rng.uniform(0.2, 0.35), 1.0)


def _ball(rng):
    r = 0.5
    return _at(M.create_sphere(r, resolution=24), 0, 0, r)


def _ring(rng):
    tube = rng.uniform(0.08, 0.16)
    return _at(M.create_torus(0.5 - tube, tube, 40, 16), 0, 0, tube)


def _cone(rng):
    return M.create_cone(rng.uniform(0.3, 0.5), 1.0, resolution=32)


def _table(rng):
    w, d, t = rng.uniform(0.9, 1.3), rng.uniform(0.6, 0.9), rng.uniform(0.04, 0.07)
    leg = rng.uniform(0.03, 0.06)
    legs = [box(leg, leg, 1.0 - t, sx * (w / 2 - leg), sy * (d / 2 - leg))
            for sx in (-1, 1) for sy in (-1, 1)]
    return _merge(legs + [box(w, d, t, z=1.0 - t)])


def _chair(rng):
    s, seat_h, leg = rng.uniform(0.4, 0.5), rng.uniform(0.42, 0.5), 0.04
    legs = [box(leg, leg, seat_h, sx * (s / 2 - leg), sy * (s / 2 - leg))
            for sx in (-1, 1) for sy in (-1, 1)]
    back = box(s, 0.04, 1.0 - seat_h - 0.04, y=s / 2 - 0.02, z=seat_h + 0.04)
    return _merge(legs + [box(s, s, 0.04, z=seat_h), back])


def _mug(rng):
    r = rng.uniform(0.28, 0.36)
    handle = M.create_torus(0.2, 0.05, 24, 12)
    handle.rotate(o3d.geometry.get_rotation_matrix_from_xyz((np.pi / 2, 0, 0)), (0, 0, 0))
    return _merge([cylinder(r, 1.0, resolution=32), _at(handle, r + 0.1, 0, 0.5)])


def _bottle(rng):
    r, body = rng.uniform(0.18, 0.26), rng.uniform(0.55, 0.65)
    neck_r = rng.uniform(0.06, 0.09)
    shoulder = _at(M.create_cone(r, 0.2, resolution=24), 0, 0, body)
    return _merge([cylinder(r, body), shoulder, cylinder(neck_r, 1.0 - body - 0.1, z=body + 0.1)])


def _lamp(rng):
    base_r = rng.uniform(0.2, 0.3)
    shade = M.create_cone(rng.uniform(0.25, 0.35), 0.3, resolution=24)
    return _merge([cylinder(base_r, 0.05), cylinder(0.025, 0.75, z=0.05),
                   _at(shade, 0, 0, 0.7)])


def _bowl(rng):
    r = 0.5
    mesh = M.create_sphere(r, resolution=30)
    v = np.asarray(mesh.vertices)
    tris = np.asarray(mesh.triangles)
    keep = np.all(v[tris][:, :, 2] <= 1e-9, axis=1)        # the lower hemisphere, open
    mesh.triangles = o3d.utility.Vector3iVector(tris[keep])
    mesh.remove_unreferenced_vertices()
    v = np.asarray(mesh.vertices) * np.array([1.0, 1.0, rng.uniform(0.5, 0.9)])
    mesh.vertices = o3d.utility.Vector3dVector(v)
    return _at(mesh, 0, 0, -v[:, 2].min())


def _blob(rng):
    mesh = smooth_blob(rng)
    v = np.asarray(mesh.vertices)
    return _at(mesh, 0, 0, -v[:, 2].min())


CLASSES = {"cabinet": _cabinet, "can": _can, "ball": _ball, "ring": _ring, "cone": _cone,
           "table": _table, "chair": _chair, "mug": _mug, "bottle": _bottle, "lamp": _lamp,
           "bowl": _bowl, "blob": _blob}


def make_object(name, rng):
    """A mesh of class ``name`` in canonical pose, scaled to height 1 (the ring: diameter 1)."""
    if name not in CLASSES:
        raise ValueError(f"unknown object class {name!r}; known: {sorted(CLASSES)}")
    mesh = CLASSES[name](rng)
    mesh.compute_triangle_normals()
    return mesh


def sample_surface(mesh, n, rng):
    """``(points [n, 3], normals [n, 3])`` uniform on the mesh surface (area-weighted)."""
    cloud = Cloud(np.asarray(mesh.vertices, np.float32),
                  faces=np.asarray(mesh.triangles, np.int32))
    s = sample_mesh(cloud, n, rng)
    return s.points, s.normals
