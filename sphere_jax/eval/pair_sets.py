"""Benchmark inputs: sets of scans with ground-truth pair transforms, prepared the same way for
every method (CONVENTIONS.md §7: 2 cm voxel, normals from 17 neighbours, 5000 keypoints).

A :class:`PairSet` is one 3DMatch-layout scene or one Stanford ``.conf`` scan set;
:func:`find_pair_sets` recognises either under a root folder. :func:`prepare` turns each scan
into a :class:`Fragment` (voxelised points, normals, keypoints), optionally rotated by a seeded
random rotation about the origin (the "rotated 3DMatch" variant), with the ground truth
rotated to match.
"""
from __future__ import annotations

import dataclasses
import glob
import os
import warnings
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from sphere_jax import checks
from sphere_jax.data import augment, patches, scan_roots
from sphere_jax.data.poses import overlap, transform
from sphere_jax.data.readers import stanford, threedmatch
from sphere_jax.registration.fragments import Fragment, fragment


@dataclasses.dataclass
class PairSet:
    """Scans ``keys`` (read by ``load(key) -> [N, 3]``) and ``transforms[(i, j)]``: p_i = T p_j.
    ``keypoints(key)`` gives release keypoint coordinates ``[K, 3]`` or None."""
    name: str
    keys: list
    transforms: dict
    load: Callable
    keypoints: Callable = lambda key: None

    @property
    def pairs(self):
        return sorted(self.transforms)


def fragment_scene(scene: threedmatch.FragmentScene) -> PairSet:
    if scene.skipped:
        warnings.warn(f"{scene.name}: {len(scene.skipped)} ground-truth pair(s) skipped, their "
                      f"clouds are missing (partial download?)", stacklevel=2)

    def keypoints(k):
        path = os.path.join(scene.fragment_dir, f"cloud_bin_{k}_keypoints.txt")
        if not os.path.isfile(path):
            return None
        cloud = scene.cloud(k).points
        return cloud[threedmatch.read_keypoint_indices(path, len(cloud))]

    return PairSet(scene.name, list(scene.fragments), dict(scene.transforms),
                   lambda k: scene.cloud(k).points, keypoints)


def stanford_scans(conf_path, voxel, min_overlap=0.10) -> PairSet:
    """The scans of a Stanford ``.conf``; pairs whose overlap (fraction of either scan within
    2 voxels of the other under the ground truth) exceeds ``min_overlap``, as the seed's
    Stanford Views protocol."""
    scans = stanford.load_stanford_scans(conf_path)
    clouds = {k: patches.voxel_downsample(scans.cloud(k).points, voxel) for k in scans.names}
    transforms = {}
    for a, i in enumerate(scans.names):
        for j in scans.names[a + 1:]:
            t = scans.transform(i, j)
            if overlap(clouds[i], clouds[j], t, voxel) > min_overlap:
                transforms[(i, j)] = t
    name = os.path.splitext(os.path.basename(str(conf_path)))[0]
    return PairSet(name, scans.names, transforms, lambda k: scans.cloud(k).points)


def scene_gt_dir(gt_root, scene):
    """The ground-truth folder of ``scene`` in a release of ground truth only (e.g. 3DLoMatch):
    ``<gt_root>/<scene>-evaluation/gt.log``, ``<gt_root>/<scene>/gt.log``, or ``gt_root``
    itself when it holds a ``gt.log``."""
    for d in (os.path.join(gt_root, scene + "-evaluation"), os.path.join(gt_root, scene),
              gt_root):
        if os.path.isfile(os.path.join(d, "gt.log")):
            return d
    raise checks.MissingError(f"data.gt={gt_root!r} has no gt.log for scene {scene!r} (looked "
                            f"for {scene}-evaluation/gt.log and {scene}/gt.log)")


def find_pair_sets(root, voxel=0.02, min_overlap=0.10, gt_root=None):
    """Every scan set under ``root``: Stanford ``.conf`` files, a 3DMatch scene folder, or a
    folder of such scenes (ground truth in ``<scene>-evaluation/`` or beside the clouds, or,
    with ``gt_root``, from there: :func:`scene_gt_dir`). A scene is any folder with at least one
    ``cloud_bin_K.ply``; pairs whose clouds are absent are skipped with a warning."""
    confs, dirs = scan_sets_under(root, gt_root)
    if confs:
        return [stanford_scans(c, voxel, min_overlap) for c in confs]
    gt = (lambda d: None) if gt_root is None else (
        lambda d: scene_gt_dir(str(gt_root), os.path.basename(d)))
    return [fragment_scene(threedmatch.load_fragment_scene(d, gt(d))) for d in dirs]


def scan_sets_under(root, gt_root=None):
    """``(Stanford .conf files, 3DMatch scene folders)`` under ``root`` by their names alone
    (nothing is read), so an evaluation can refuse a root without scans before any work;
    :class:`~sphere_jax.checks.MissingError` when there is neither."""
    root = os.path.normpath(str(root))
    if not os.path.isdir(root):
        raise checks.MissingError(f"data root {root!r} is not a folder")
    if gt_root is not None and not os.path.isdir(str(gt_root)):
        raise checks.MissingError(f"data.gt={gt_root!r} is not a folder")
    confs = sorted(glob.glob(os.path.join(root, "*.conf")) +
                   glob.glob(os.path.join(root, "*", "*.conf")))
    if confs:
        return confs, []
    if glob.glob(os.path.join(root, "cloud_bin_*.ply")):
        return [], [root]
    dirs = sorted({os.path.dirname(p) for p in glob.glob(os.path.join(root, "*",
                                                                        "cloud_bin_*.ply"))})
    if not dirs:
        raise checks.MissingError(f"{root}: no Stanford .conf, no cloud_bin_K.ply fragments and "
                                  f"no scene folders holding them")
    return [], dirs


def rotations_for(pair_set: PairSet, seed):
    """One seeded random rotation per scan (4×4), the same for every method."""
    rng = np.random.default_rng([seed, sum(map(ord, pair_set.name))])
    out = {}
    for k in pair_set.keys:
        t = np.eye(4)
        t[:3, :3] = augment.random_rotations(rng)
        out[k] = t
    return out


def rotate(pair_set: PairSet, seed) -> tuple[PairSet, dict]:
    """The rotated variant: scan k turned by R_k about the origin, so p_i = R_i T R_jᵀ p_j."""
    rot = rotations_for(pair_set, seed)
    transforms = {(i, j): rot[i] @ t @ rot[j].T for (i, j), t in pair_set.transforms.items()}

    def load(k):
        return transform(pair_set.load(k), rot[k]).astype(np.float32)

    def keypoints(k):
        kp = pair_set.keypoints(k)
        return None if kp is None else transform(kp, rot[k])

    return PairSet(pair_set.name, pair_set.keys, transforms, load, keypoints), rot


def prepare(pair_set: PairSet, key, voxel=0.02, n_keypoints=5000, normal_k=17, seed=0,
            viewpoint=(0.0, 0.0, 0.0)) -> Fragment:
    """:func:`fragment` of scan ``key``: the release's keypoints when it has them, else
    ``n_keypoints`` random ones seeded by ``seed`` and the scan's place in the set."""
    return fragment(key, pair_set.load(key), voxel,
                    np.random.default_rng([seed, pair_set.keys.index(key)]), n_keypoints,
                    normal_k, viewpoint, pair_set.keypoints(key))


def prepare_all(pair_set: PairSet, seed=0, progress=False, **prepare_kwargs) -> dict:
    """:func:`prepare` for every scan that takes part in a pair: ``{key: Fragment}``."""
    keys = sorted({k for p in pair_set.pairs for k in p}, key=pair_set.keys.index)
    return {k: prepare(pair_set, k, seed=seed, **prepare_kwargs)
            for k in tqdm(keys, desc=f"{pair_set.name}: prepare", disable=not progress)}


# ---- the scans of an evaluation config ----------------------------------------------------------

def data_root(config):
    if config.data.root:
        return config.data.root
    return scan_roots.default_scan_root()


def check_data(config):
    """:class:`~sphere_jax.checks.ConfigError` when ``config.data.root`` (or ``data.gt``) holds
    no scan set: checked by :func:`sphere_jax.eval.tasks.run` before the workdir is claimed
    (the embedded default is generated on first use, not checked)."""
    if config.data.get("root"):
        try:
            scan_sets_under(config.data.root, config.data.get("gt") or None)
        except checks.MissingError as e:
            raise checks.ConfigError(f"config.data.root: {e}") from None


def pair_sets(config):
    """The scan sets of ``config.data`` (scene filter, pair limit, rotated variant applied)."""
    sets = find_pair_sets(data_root(config), config.data.voxel,
                          config.data.get("min_overlap", 0.10), config.data.get("gt") or None)
    if config.data.scenes:
        wanted = [s.strip() for s in config.data.scenes.split(",") if s.strip()]
        unknown = sorted(set(wanted) - {s.name for s in sets})
        if unknown:
            raise checks.ConfigError("config.data.scenes", "comma-separated scene names "
                                     f"among {[s.name for s in sets]}", config.data.scenes)
        sets = [s for s in sets if s.name in wanted]
    out = []
    for s in sets:
        if config.data.max_pairs:
            s.transforms = {p: s.transforms[p] for p in s.pairs[:config.data.max_pairs]}
        if not s.transforms:
            warnings.warn(f"{s.name}: no pairs with ground truth; skipped", stacklevel=2)
            continue
        out.append(rotate(s, config.seed)[0] if config.rotate else s)
    if not out:
        raise ValueError(f"no scan pairs with ground truth under {data_root(config)!r}")
    return out


def prepare_kwargs(config):
    d = config.data
    return dict(voxel=d.voxel, n_keypoints=d.n_keypoints, normal_k=d.normal_k)
