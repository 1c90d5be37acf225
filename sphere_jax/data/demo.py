"""Data for the notebooks and examples: the real scans (:func:`sphere_jax.paths.real_data_root`)
when present, else the embedded synthetic scans, and the shipped bundles."""
from __future__ import annotations

import os

from sphere_jax import paths
from sphere_jax.data import scan_roots
from sphere_jax.data.readers import stanford, threedmatch

real_data_root = paths.real_data_root


def real_data_label():
    """Where the real scans are, relative to the checkout (``../shared/data``), or why none."""
    root = real_data_root()
    return paths.relative(root) if root else "not found: the synthetic scans stand in for it"


def fragment_pair():
    """``((src [N, 3], dst [M, 3]), T)`` with ``p_dst = T p_src``: 3DMatch redkitchen
    fragments 5 → 0, or the first pair of the synthetic rooms."""
    root = real_data_root()
    if root:
        d = os.path.join(root, "3dmatch", "7-scenes-redkitchen")
        scene = threedmatch.load_fragment_scene(d, d + "-evaluation")
        i, j = 0, 5
    else:
        import glob
        d = sorted(glob.glob(os.path.join(scan_roots.default_scan_root(), "*", "cloud_bin_0.ply")))
        scene = threedmatch.load_fragment_scene(os.path.dirname(d[0]))
        i, j = scene.pairs[0]
    return (scene.cloud(j).points, scene.cloud(i).points), scene.transforms[(i, j)]


def scan_pair():
    """``((a, b), T, radius, voxel)`` with ``p_a = T p_b``: Stanford bunny scans bun000 and
    bun045 (1.5 cm supports on a 1 mm grid), or a synthetic fragment pair (0.3 m, 2 cm)."""
    root = real_data_root()
    if root:
        scans = stanford.load_stanford_scans(os.path.join(root, "stanford", "bunny", "data",
                                                          "bun.conf"))
        a, b = "bun000.ply", "bun045.ply"
        return (scans.cloud(a).points, scans.cloud(b).points), scans.transform(a, b), 0.015, 0.001
    (src, dst), t = fragment_pair()
    return (dst, src), t, 0.3, 0.02
