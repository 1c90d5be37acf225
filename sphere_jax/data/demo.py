"""Data for the notebooks and examples: the real scans of ``../shared/data`` when they sit
beside the checkout (or ``$SPHERE_JAX_REAL_DATA``), else the embedded synthetic scans, and the
shipped bundles."""
from __future__ import annotations

import os

from sphere_jax.data import datasets, pipeline

_REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def real_data_root():
    """``$SPHERE_JAX_REAL_DATA`` or ``<checkout>/../shared/data`` if present, else None."""
    for root in (os.environ.get("SPHERE_JAX_REAL_DATA"),
                 os.path.join(_REPO, "..", "shared", "data"),
                 os.path.join(os.getcwd(), "..", "..", "shared", "data")):
        if root and os.path.isdir(os.path.join(root, "3dmatch")):
            return os.path.normpath(root)
    return None


def bundle(name):
    """Path of a shipped bundle, e.g. ``bundle('sound_cpu')``."""
    for root in (os.environ.get("SPHERE_JAX_CHECKPOINTS"), os.path.join(_REPO, "checkpoints"),
                 os.path.join(os.getcwd(), "..", "checkpoints"),
                 os.path.join(os.getcwd(), "checkpoints")):
        if root and os.path.isfile(os.path.join(root, name, "bundle", "config.json")):
            return os.path.normpath(os.path.join(root, name, "bundle"))
    raise FileNotFoundError(f"no shipped bundle {name!r}: set SPHERE_JAX_CHECKPOINTS to the "
                            f"repository's checkpoints/ folder")


def fragment_pair():
    """``((src [N, 3], dst [M, 3]), T)`` with ``p_dst = T p_src``: 3DMatch redkitchen
    fragments 5 → 0, or the first pair of the synthetic rooms."""
    root = real_data_root()
    if root:
        d = os.path.join(root, "3dmatch", "7-scenes-redkitchen")
        scene = datasets.load_fragment_scene(d, d + "-evaluation")
        i, j = 0, 5
    else:
        import glob
        d = sorted(glob.glob(os.path.join(pipeline.default_scan_root(), "*", "cloud_bin_0.ply")))
        scene = datasets.load_fragment_scene(os.path.dirname(d[0]))
        i, j = scene.pairs[0]
    return (scene.cloud(j).points, scene.cloud(i).points), scene.transforms[(i, j)]


def scan_pair():
    """``((a, b), T, radius, voxel)`` with ``p_a = T p_b``: Stanford bunny scans bun000 and
    bun045 (1.5 cm supports on a 1 mm grid), or a synthetic fragment pair (0.3 m, 2 cm)."""
    root = real_data_root()
    if root:
        scans = datasets.load_stanford_scans(os.path.join(root, "stanford", "bunny", "data",
                                                          "bun.conf"))
        a, b = "bun000.ply", "bun045.ply"
        return (scans.cloud(a).points, scans.cloud(b).points), scans.transform(a, b), 0.015, 0.001
    (src, dst), t = fragment_pair()
    return (dst, src), t, 0.3, 0.02
