"""A synthetic object set in the Washington RGB-D Object layout (read back by
:mod:`sphere_jax.data.readers.washington`): each category × a few instances on a table, filmed
by the virtual Kinect of :mod:`.camera` in three turntable videos."""
from __future__ import annotations

import os

import numpy as np

from sphere_jax.data.generators import camera as cam
from sphere_jax.data.generators import shapes
from sphere_jax.data.readers import threedmatch
from sphere_jax.data.readers.io import atomic_write
from sphere_jax.data.readers.rgbd import write_png

CATEGORIES = ["ball", "bottle", "bowl", "can", "cone", "mug", "ring", "blob", "cabinet", "lamp"]
VIDEOS = {1: 0.52, 2: 0.79, 4: 1.05}                         # elevation (rad) per video


def make_synthetic(out_dir, seed, instances=3, frames=6, camera=None, margin=4):
    """Each category × ``instances`` objects (own shape, size and colour around a category
    hue), filmed on a table by the virtual Kinect in the three videos × ``frames`` azimuths."""
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
                 ("\n".join(threedmatch.format_matrix(camera.intrinsics)) + "\n").encode())
    return {"frames": count}
