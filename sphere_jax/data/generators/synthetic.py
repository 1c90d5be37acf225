"""Deterministic synthetic data, written in the real benchmarks' layouts (no download).

* **Indoor scenes** (3DMatch layout): a room with furniture-like boxes, cylinders, spheres, tori
  and random smooth meshes, observed along a loop by the virtual Kinect of :mod:`camera`;
  consecutive views are fused into fragments with ground-truth poses, overlaps are computed,
  and pairs are listed in ``gt.log`` (overlap > 30 %) and the 3DLoMatch variant (10–30 %).
* **Shapes** (ModelNet40 ``modelnet40_normal_resampled`` layout): the classes of
  :mod:`shapes` in canonical pose, 10 000 surface points with normals each.
* **Object frames** (RGB-D): objects on a table seen from around it, with colour, depth,
  instance masks, and per-instance category, 2-D box and pose (for the recognition pipelines).

Same seed → byte-identical files.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks, paths
from sphere_jax.data import patches
from sphere_jax.data.readers import io, rgbd, threedmatch

# The renderer (open3d, with `camera`, `shapes` and `washington` on it) is imported only where
# data are made: reading an existing cache, or training on scans, must not need open3d (an
# accelerator machine may not have it).

# Categories that furnish the rooms (at furniture scale) and populate the table tops.
ROOM_OBJECTS = ["cabinet", "table", "chair", "can", "ball", "ring", "blob", "lamp", "cone"]
TABLE_OBJECTS = ["can", "ball", "ring", "cone", "mug", "bottle", "bowl", "blob", "cabinet"]


def _place(rng, radius, half_w, half_d, placed, tries=50):
    """A centre for a footprint of ``radius`` inside ``[-half_w, half_w] × [-half_d, half_d]``
    that overlaps no footprint in ``placed`` (rejection sampling); None if none was found."""
    for _ in range(tries):
        xy = rng.uniform([-half_w + radius, -half_d + radius], [half_w - radius, half_d - radius])
        if all(np.linalg.norm(xy - p) > radius + r for p, r in placed):
            return xy
    return None


def _rotate_z(mesh, angle):
    import open3d as o3d
    return mesh.rotate(o3d.geometry.get_rotation_matrix_from_xyz((0, 0, angle)), (0, 0, 0))


# ----------------------------------------------------------------------------------------------
# Rooms and fragments
# ----------------------------------------------------------------------------------------------

def make_room(rng):
    """Meshes and albedos of a furnished room; returns ``(meshes, albedos, (W, D, H))``."""
    from sphere_jax.data.generators import shapes
    w, d, h = rng.uniform(4.0, 6.0), rng.uniform(3.5, 5.0), rng.uniform(2.4, 2.9)
    t = 0.05
    meshes = [shapes.box(w, d, t, z=-t), shapes.box(w, d, t, z=h),
              shapes.box(t, d, h, x=-w / 2), shapes.box(t, d, h, x=w / 2),
              shapes.box(w, t, h, y=-d / 2), shapes.box(w, t, h, y=d / 2)]
    albedos = [rng.uniform(0.3, 0.6, 3)] * 2 + [rng.uniform(0.5, 0.9, 3)] * 4
    placed = []
    for _ in range(rng.integers(9, 14)):
        name = ROOM_OBJECTS[rng.integers(len(ROOM_OBJECTS))]
        size = rng.uniform(0.4, 1.1)
        mesh = _rotate_z(shapes.make_object(name, rng).scale(size, (0, 0, 0)),
                         rng.uniform(0, 2 * np.pi))
        ext = np.asarray(mesh.vertices)[:, :2]
        radius = np.linalg.norm(ext, axis=1).max()
        xy = _place(rng, radius, w / 2, d / 2, placed)
        if xy is None:
            continue
        placed.append((xy, radius))
        meshes.append(mesh.translate((xy[0], xy[1], 0.0)))
        albedos.append(rng.uniform(0.15, 0.95, 3))
    for m in meshes:
        m.compute_triangle_normals()
    return meshes, np.array(albedos), (w, d, h)


def loop_trajectory(rng, room_size, n_frames):
    """Camera-to-world poses along a loop inside the room, looking across it at the far walls."""
    from sphere_jax.data.generators import camera as cam
    w, d, h = room_size
    phase, wobble = rng.uniform(0, 2 * np.pi), rng.uniform(0.05, 0.15)
    poses = []
    for k in range(n_frames):
        th = phase + 2 * np.pi * k / n_frames
        eye = [0.3 * w * np.cos(th), 0.3 * d * np.sin(th),
               1.5 + wobble * np.sin(3 * th)]
        look = th + np.pi + 0.6 * np.sin(2 * th)
        target = [0.5 * w * np.cos(look), 0.5 * d * np.sin(look), 0.8 + 0.3 * np.cos(5 * th)]
        poses.append(cam.look_at(eye, target))
    return np.array(poses)


def information_matrix(p_Kx3):
    """The 6×6 information matrix of gt.info from corresponding points p (in fragment i's
    frame): ``Σ Gᵀ G`` with ``G = [I | -[p]×]``."""
    x, y, z = np.asarray(p_Kx3, np.float64).T
    g = np.zeros((len(x), 3, 6))
    g[:, [0, 1, 2], [0, 1, 2]] = 1
    g[:, 0, 4], g[:, 0, 5] = z, -y
    g[:, 1, 3], g[:, 1, 5] = -z, x
    g[:, 2, 3], g[:, 2, 4] = y, -x
    return np.einsum("nki,nkj->ij", g, g)


# What TSDF fusion of many views leaves of the sensor's depth noise (metres, along the ray).
FUSED_NOISE = 0.003


def fused_depth(scene, camera, pose, sensor_depth_HxW, rng):
    """The depth a fragment keeps of one view: the exact surface where the sensor returned a
    depth (its holes and grazing dropouts stay), with ``FUSED_NOISE``.

    The union of 30 raw views is centimetres thick — Kinect noise and disparity steps reach
    2–5 cm at 3–4 m, and near a 5 cm wall they even cross it (measured on the fragments before:
    a 10 cm neighbourhood held twice a plane's points in two layers 5 cm apart, 25 mm residual)
    — where 3DMatch's TSDF fragments have mm-level surfaces."""
    exact, _, _ = scene.render(camera, pose)
    noise = rng.normal(0.0, FUSED_NOISE, exact.shape)
    return np.where(sensor_depth_HxW > 0, exact + noise, 0.0).astype(np.float32)


# Overlap ratios and information matrices are estimated from this many points of fragment j.
_OVERLAP_SAMPLES = 20000


def make_scene(out_root, name, seed, n_frames=120, frames_per_fragment=30, stride=10,
               voxel=0.025, camera=None):
    """Render, fuse and write one scene in the 3DMatch layout under ``out_root``:
    ``<name>/cloud_bin_K.{ply,info.txt}``, ``<name>-evaluation/gt.{log,info}``,
    ``gt_overlap.log``, and ``3DLoMatch/<name>-evaluation/``. Returns the scene summary.
    ``camera``: a :class:`camera.Camera` (default: its defaults)."""
    from sphere_jax.data.generators import camera as cam
    camera = camera or cam.Camera()
    rng = np.random.default_rng(seed)
    meshes, albedos, size = make_room(rng)
    scene = cam.Scene(meshes, albedos)
    poses = loop_trajectory(rng, size, n_frames)
    frag_dir = os.path.join(out_root, name)
    os.makedirs(frag_dir, exist_ok=True)
    frames = []
    for pose in poses:
        depth, color, _ = scene.render(camera, pose, rng)
        frames.append(rgbd.depth_to_cloud(fused_depth(scene, camera, pose, depth, rng),
                                          camera.intrinsics, color, pose, depth_scale=1.0))
    fragments, frag_poses = [], []
    starts = range(0, n_frames, stride)                       # the loop closes: wrap around
    for k, s in enumerate(starts):
        idx = [(s + f) % n_frames for f in range(frames_per_fragment)]
        pts = np.concatenate([frames[i].points for i in idx])
        cols = np.concatenate([frames[i].colors for i in idx])
        keep = patches.voxel_downsample(pts, voxel, return_index=True)
        a = poses[s]                                         # fragment frame = first camera
        local = (patches.voxel_downsample(pts, voxel) - a[:3, 3]) @ a[:3, :3]   # voxel means
        io.write_ply(os.path.join(frag_dir, f"cloud_bin_{k}.ply"), local, colors=cols[keep])
        info = f"{name}\t seq-01\t {s}\t {s + frames_per_fragment - 1}\t\n" + "\n".join(
            threedmatch.format_matrix(a, "\t"))
        io.atomic_write(os.path.join(frag_dir, f"cloud_bin_{k}.info.txt"), (info + "\n").encode())
        fragments.append(local.astype(np.float32))
        frag_poses.append(a)
    n = len(fragments)
    transforms, overlaps, infos = {}, {}, {}
    trees = [KDTree(f) for f in fragments]
    samples = [f[np.random.default_rng(seed + k).choice(len(f), min(len(f), _OVERLAP_SAMPLES),
                                                          replace=False)]
               for k, f in enumerate(fragments)]
    for i in range(n):
        for j in range(i + 1, n):
            t = np.linalg.inv(frag_poses[i]) @ frag_poses[j]        # p_i = T p_j
            pj = samples[j] @ t[:3, :3].T + t[:3, 3]
            dist, idx = trees[i].query(pj, k=1)
            close = dist[:, 0] < 3 * voxel
            ratio = float(np.mean(close))
            if ratio > 0.1:
                transforms[(i, j)], overlaps[(i, j)] = t, ratio
                infos[(i, j)] = information_matrix(fragments[i][idx[close, 0]])
    for sub, lo, hi in (("", 0.3, 1.01), ("3DLoMatch", 0.1, 0.3)):
        ev = os.path.join(out_root, sub, name + "-evaluation")
        os.makedirs(ev, exist_ok=True)
        pick = {p: transforms[p] for p in transforms if lo < overlaps[p] <= hi}
        threedmatch.write_gt_log(os.path.join(ev, "gt.log"), pick, n)
        threedmatch.write_pair_blocks(os.path.join(ev, "gt.info"), {p: infos[p] for p in pick}, n)
        threedmatch.write_gt_overlap(os.path.join(ev, "gt_overlap.log"),
                                  {p: overlaps[p] for p in pick})
    return {"name": name, "fragments": n, "pairs": len([p for p in overlaps
                                                         if overlaps[p] > 0.3]),
            "lo_pairs": len([p for p in overlaps if 0.1 < overlaps[p] <= 0.3])}


# ----------------------------------------------------------------------------------------------
# Shapes (ModelNet layout)
# ----------------------------------------------------------------------------------------------

def make_shapes(out_dir, seed, per_class=20, n_points=10000, test_fraction=0.25):
    """``<class>/<class>_NNNN.txt`` (x,y,z,nx,ny,nz), ``shape_names.txt``, ``train.txt`` and
    ``test.txt``: objects centred and scaled into the unit sphere, in canonical pose."""
    from sphere_jax.data.generators import shapes
    rng = np.random.default_rng(seed)
    names = sorted(shapes.CLASSES)
    train, test = [], []
    for name in names:
        os.makedirs(os.path.join(out_dir, name), exist_ok=True)
        for k in range(per_class):
            pts, nrm = shapes.sample_surface(shapes.make_object(name, rng), n_points, rng)
            pts = pts - (pts.max(0) + pts.min(0)) / 2
            pts = pts / np.linalg.norm(pts, axis=1).max()
            shape_id = f"{name}_{k + 1:04d}"
            rows = "\n".join(",".join(f"{v:.6f}" for v in r) for r in np.hstack([pts, nrm]))
            io.atomic_write(os.path.join(out_dir, name, shape_id + ".txt"), (rows + "\n").encode())
            n_test = max(1, int(round(per_class * test_fraction))) if per_class > 1 else 0
            (test if k >= per_class - n_test else train).append(shape_id)
    for fname, items in (("shape_names.txt", names), ("train.txt", train), ("test.txt", test)):
        io.atomic_write(os.path.join(out_dir, fname), ("\n".join(items) + "\n").encode())
    return {"classes": len(names), "train": len(train), "test": len(test)}


# ----------------------------------------------------------------------------------------------
# RGB-D object frames (recognition)
# ----------------------------------------------------------------------------------------------

def make_object_frames(out_dir, seed, n_scenes=4, views_per_scene=6, camera=None):
    """Table-top scenes of 3–6 objects; per view ``frame-N.{color,depth,mask}.png``,
    ``frame-N.pose.txt`` (camera-to-world) and ``frame-N.labels.json`` (instances: id in the
    mask, category, box [u0, v0, u1, v1] in pixels, 4×4 object-to-world pose)."""
    import open3d as o3d
    from sphere_jax.data.generators import camera as cam
    from sphere_jax.data.generators import shapes
    camera = camera or cam.Camera()
    rng = np.random.default_rng(seed)
    os.makedirs(out_dir, exist_ok=True)
    frame = 0
    for _ in range(n_scenes):
        table_h, tw, td = rng.uniform(0.7, 0.8), rng.uniform(1.0, 1.4), rng.uniform(0.7, 0.9)
        meshes = [shapes.box(6, 6, 0.05, z=-0.05), shapes.box(tw, td, table_h)]
        albedos = [rng.uniform(0.3, 0.5, 3), rng.uniform(0.5, 0.8, 3)]
        instances, placed = [], []
        for _ in range(rng.integers(3, 7)):
            name = TABLE_OBJECTS[rng.integers(len(TABLE_OBJECTS))]
            size, yaw = rng.uniform(0.12, 0.28), rng.uniform(0, 2 * np.pi)
            mesh = _rotate_z(shapes.make_object(name, rng).scale(size, (0, 0, 0)), yaw)
            radius = np.linalg.norm(np.asarray(mesh.vertices)[:, :2], axis=1).max()
            xy = _place(rng, radius, tw / 2, td / 2, placed)
            if xy is None:
                continue
            placed.append((xy, radius))
            mesh.translate((xy[0], xy[1], table_h))
            mesh.compute_triangle_normals()
            pose = np.eye(4)
            pose[:3, :3] = o3d.geometry.get_rotation_matrix_from_xyz((0, 0, yaw)) * size
            pose[:3, 3] = (xy[0], xy[1], table_h)
            instances.append({"id": len(instances) + 1, "category": name,
                              "pose": pose.round(6).tolist(), "geometry": len(meshes)})
            meshes.append(mesh)
            albedos.append(rng.uniform(0.1, 1.0, 3))
        scene = cam.Scene(meshes, albedos)
        for v in range(views_per_scene):
            th = 2 * np.pi * v / views_per_scene + rng.uniform(-0.2, 0.2)
            dist, elev = rng.uniform(0.9, 1.3), rng.uniform(0.5, 0.9)
            eye = [dist * np.cos(th) * np.cos(elev), dist * np.sin(th) * np.cos(elev),
                   table_h + dist * np.sin(elev)]
            pose = cam.look_at(eye, [0, 0, table_h + 0.05])
            depth, color, ids = scene.render(camera, pose, rng)
            mask = np.zeros(ids.shape, np.uint16)
            labels = []
            for inst in instances:
                sel = ids == inst["geometry"]
                if sel.sum() < 20:
                    continue
                mask[sel] = inst["id"]
                vv, uu = np.nonzero(sel)
                labels.append({"id": inst["id"], "category": inst["category"],
                               "box": [int(uu.min()), int(vv.min()), int(uu.max()), int(vv.max())],
                               "pose": inst["pose"]})
            stem = os.path.join(out_dir, f"frame-{frame:06d}")
            rgbd.write_png(stem + ".color.png", color)
            rgbd.write_png(stem + ".depth.png", np.round(depth * 1000).astype(np.uint16))
            rgbd.write_png(stem + ".mask.png", mask)
            io.atomic_write(stem + ".pose.txt",
                            ("\n".join(threedmatch.format_matrix(pose)) + "\n").encode())
            io.atomic_write(stem + ".labels.json", json.dumps(
                {"instances": labels}, indent=1).encode())
            frame += 1
    io.atomic_write(os.path.join(out_dir, "camera-intrinsics.txt"),
                    ("\n".join(threedmatch.format_matrix(camera.intrinsics)) + "\n").encode())
    return {"frames": frame}


# ----------------------------------------------------------------------------------------------
# Everything
# ----------------------------------------------------------------------------------------------

def make_all(out_dir, seed=0, n_scenes=2, scene_kwargs=None, shape_kwargs=None,
             object_kwargs=None):
    """The default data: ``3dmatch/`` scenes, ``modelnet/`` shapes, ``objects/`` RGB-D frames,
    and ``summary.json`` (written last: its presence marks a complete set)."""
    summary = {"seed": seed, "scenes": [
        make_scene(os.path.join(out_dir, "3dmatch"), f"synth-room-{k}", seed * 1000 + k,
                   **(scene_kwargs or {})) for k in range(n_scenes)]}
    summary["shapes"] = make_shapes(os.path.join(out_dir, "modelnet"), seed * 1000 + 101,
                                    **(shape_kwargs or {}))
    summary["objects"] = make_object_frames(os.path.join(out_dir, "objects"), seed * 1000 + 202,
                                            **(object_kwargs or {}))
    # The same seed gives the same bytes on one machine, but the floats of another CPU may
    # not: the fingerprints let two machines' results be traced to their data.
    summary["fingerprints"] = {name: fingerprint(os.path.join(out_dir, name))
                               for name in ("3dmatch", "modelnet", "objects")}
    io.atomic_write(os.path.join(out_dir, "summary.json"), json.dumps(summary, indent=1).encode())
    return summary


def fingerprint(folder):
    """SHA-256 (hex) of every file under ``folder``: their relative paths and contents, in
    sorted order."""
    h = hashlib.sha256()
    for dirpath, dirs, files in os.walk(folder):
        dirs.sort()
        for name in sorted(files):
            path = os.path.join(dirpath, name)
            h.update(os.path.relpath(path, folder).encode() + b"\0")
            with open(path, "rb") as f:
                h.update(hashlib.sha256(f.read()).digest())
    return h.hexdigest()


DATA_VERSION = 2


def default_data_dir(seed=0):
    """Where the default synthetic data lives: ``$SPHERE_JAX_DATA`` or ``~/.cache/sphere_jax``."""
    return os.path.join(paths.cache_root(), f"synthetic-v{DATA_VERSION}-seed{seed}")


def ensure_default_data(seed=0, out_dir=None):
    """The default data directory, generated on first use (into a temporary folder renamed
    into place when complete, so an interrupted run never leaves a half-written set)."""
    out_dir = out_dir or default_data_dir(seed)
    if os.path.isfile(os.path.join(out_dir, "summary.json")):
        return out_dir
    tmp = f"{out_dir}.partial{os.getpid()}"
    make_all(tmp, seed)
    os.makedirs(os.path.dirname(out_dir) or ".", exist_ok=True)
    _move_into_place(tmp, out_dir, "summary.json")
    return out_dir


DEFAULT_KINDS = ("3dmatch", "modelnet", "objects", "washington")


def default_root(kind, seed=0):
    """The folder of one kind of the default synthetic data, generated on first use: the
    rooms' fragments in the 3DMatch layout (``3dmatch``), ModelNet-like shapes (``modelnet``),
    labelled RGB-D object frames (``objects``) or object crops in the Washington layout
    (``washington``). Every default of a config or benchmark comes from here."""
    if kind not in DEFAULT_KINDS:
        raise checks.InputError("kind", f"one of {', '.join(DEFAULT_KINDS)}", repr(kind))
    if kind == "washington":
        return ensure_default_objects(seed)
    return os.path.join(ensure_default_data(seed), kind)


def training_rooms_dir(seed):
    """The 3DMatch-layout folder of the training rooms of ``seed``
    (:func:`ensure_training_rooms`)."""
    return os.path.join(paths.cache_root(), f"rooms-v{DATA_VERSION}-seed{int(seed)}", "3dmatch")


def ensure_training_rooms(seed, n_scenes=2):
    """More synthetic rooms for training (``data.root`` entry ``embedded:SEED``): ``n_scenes``
    rooms of seed ``seed`` in the 3DMatch layout, generated on first use beside the default
    data (rooms only: no shapes or table tops). Returns the folder of the scenes."""
    seed = int(seed)
    out_dir = os.path.dirname(training_rooms_dir(seed))
    done = os.path.join(out_dir, "summary.json")
    if not os.path.isfile(done):
        tmp = f"{out_dir}.partial{os.getpid()}"
        summary = {"seed": seed, "scenes": [
            make_scene(os.path.join(tmp, "3dmatch"), f"synth-room-s{seed}-{k}", seed * 1000 + k)
            for k in range(n_scenes)]}
        summary["fingerprints"] = {"3dmatch": fingerprint(os.path.join(tmp, "3dmatch"))}
        io.atomic_write(os.path.join(tmp, "summary.json"), json.dumps(summary, indent=1).encode())
        os.makedirs(os.path.dirname(out_dir) or ".", exist_ok=True)
        _move_into_place(tmp, out_dir, "summary.json")
    return os.path.join(out_dir, "3dmatch")


def _move_into_place(tmp, out_dir, last_file):
    """Rename the finished folder ``tmp`` to ``out_dir``. Two processes started on an empty
    cache both generate; the one that finishes second keeps the first one's copy (the same
    seed gives the same files) and drops its own."""
    try:
        os.replace(tmp, out_dir)
    except OSError:
        if not os.path.isfile(os.path.join(out_dir, last_file)):
            raise
        shutil.rmtree(tmp, ignore_errors=True)


def ensure_default_objects(seed=0):
    """Synthetic object crops in the Washington RGB-D layout (``washington/`` beside the
    default data), generated on first use and moved into place when complete."""
    out_dir = os.path.join(ensure_default_data(seed), "washington")
    if not os.path.isfile(os.path.join(out_dir, "camera-intrinsics.txt")):
        make_default_objects(os.path.dirname(out_dir), seed)
    return out_dir


def make_default_objects(data_dir, seed=0):
    """Write ``data_dir/washington`` (via a temporary folder renamed when complete)."""
    from sphere_jax.data.generators import washington
    out_dir = os.path.join(data_dir, "washington")
    tmp = f"{out_dir}.partial{os.getpid()}"
    summary = washington.make_synthetic(tmp, seed * 1000 + 303)
    if os.path.isdir(out_dir):
        shutil.rmtree(out_dir, ignore_errors=True)
    _move_into_place(tmp, out_dir, "camera-intrinsics.txt")
    return summary
