"""Training batches from scans (self-supervised: any folder of scans will do) and shapes.

Batches are a pure function of ``(seed, step)``: a resumed run sees exactly the batches the
uninterrupted run would have seen.
"""
from __future__ import annotations

import glob
import json
import os
import re

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks, paths, workdirs
from sphere_jax.data import augment, evaluation_scenes, fusion, patches, poses
from sphere_jax.data.readers import io, ply, rgbd
from sphere_jax.data.generators import synthetic


def find_scans(root):
    """Scan files under ``root``: a scan file itself (any suffix the readers read); the fused
    fragments of a posed RGB-D sequence (:mod:`sphere_jax.data.fusion`); 3DMatch fragments
    (``cloud_bin_K.ply``) if there are any; else every .ply / .pcd, recursively (sorted)."""
    root = str(root)
    if os.path.isfile(root) and root.lower().endswith(io.SUFFIXES):
        return [root]
    if not os.path.isdir(root):
        raise checks.MissingError(f"data root {root!r} is neither a scan file nor a folder")
    if rgbd.is_frame_sequence(root):
        return fusion.sequence_fragments(root)
    frags = sorted(glob.glob(os.path.join(root, "**", "cloud_bin_*.ply"), recursive=True))
    if frags:
        return frags
    found = sorted(p for ext in ("ply", "pcd")
                   for p in glob.glob(os.path.join(root, "**", f"*.{ext}"), recursive=True))
    if not found:
        raise checks.MissingError(f"no .ply or .pcd scans under {root!r}")
    return found


def scan_groups(roots, pack=""):
    """Scan files of each entry of a comma-separated list of folders (or scan files), one list
    per entry (:func:`resolve_root` reads each entry), so real scans can be added to the
    synthetic ones: ``embedded,embedded:1,/data/3dmatch/demo``. ``pack``: a folder of
    :func:`pack_scans` that holds every entry, read instead (:func:`packed_folders`)."""
    if pack:
        return [find_scans(folder) for folder in packed_folders(roots, pack)]
    return [find_scans(resolve_root(r)) for r in root_entries(roots)]


def resolve_root(entry):
    """The folder or file a ``data.root`` entry names: ``embedded`` the default synthetic
    rooms, ``embedded:N`` the training rooms of seed N (generated on first use),
    ``shared/<rel>`` a path under the real scans (``../shared/data``: the same config on
    every machine), anything else a path."""
    entry = str(entry)
    if entry in DEFAULT_ROOMS:
        synthetic.ensure_default_data()
    elif entry.startswith("embedded:"):
        synthetic.ensure_training_rooms(_rooms_seed(entry))
    return entry_path(entry)


DEFAULT_ROOMS = ("embedded", "embedded:0")      # the embedded default data's rooms


def _rooms_seed(entry):
    seed = entry[len("embedded:"):]
    if not seed.isdigit():
        raise checks.ConfigError("a data.root entry 'embedded:N'", "an integer seed N", entry)
    return int(seed)


def entry_path(entry):
    """Where a ``data.root`` entry's scans are (or will be, for synthetic data not yet
    generated): :func:`resolve_root` without generating anything."""
    entry = str(entry)
    if entry in DEFAULT_ROOMS:
        return os.path.join(synthetic.default_data_dir(0), "3dmatch")
    if entry.startswith("embedded:"):
        return synthetic.training_rooms_dir(_rooms_seed(entry))
    if entry.startswith("shared/"):
        found = paths.real_data(*entry[len("shared/"):].split("/"))
        if found is None:
            raise checks.MissingError(f"data.root entry {entry!r} is under the real scans, "
                                      f"which are not here (../shared/data, or "
                                      f"$SPHERE_JAX_REAL_DATA)")
        return found
    return entry


def root_entries(roots):
    """The entries of a comma-separated ``data.root`` (``['embedded']`` for an empty one)."""
    return [r.strip() for r in str(roots).split(",") if r.strip()] or ["embedded"]


def scan_paths(roots):
    """The scan files of :func:`scan_groups`, in one list."""
    return [p for group in scan_groups(roots) for p in group]


def parse_weights(text, n_groups):
    """``data.root_weights``: '' (every keypoint equally likely) or one non-negative number per
    entry of ``data.root`` (the share of each entry's keypoints in a batch), normalised."""
    if not str(text).strip():
        return None
    try:
        w = np.array([float(x) for x in str(text).split(",")], np.float64)
    except ValueError:
        raise ValueError(f"data.root_weights must be comma-separated numbers, got {text!r}")
    if len(w) != n_groups or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError(f"data.root_weights must be {n_groups} finite non-negative numbers "
                         f"(one per data.root entry) with a positive sum, got {text!r}")
    return w / w.sum()


def default_scan_root():
    return synthetic.default_root("3dmatch")


class PatchSource:
    """Keypoints of a set of scans and deterministic batches of unit-ball patches."""

    def __init__(self, scan_paths, voxel, keypoint_leaf, radius, n_points, min_points,
                 val_fraction=0.1, seed=0, groups=None, weights=None):
        """``groups`` (one int per scan) and ``weights`` (one share per group) draw a batch's
        keypoints group by group (e.g. as much real as synthetic data); without them every
        keypoint is equally likely."""
        self.radius, self.n_points, self.min_points = radius, n_points, min_points
        self.seed, self.scan_paths, self.voxel = seed, list(scan_paths), voxel
        self._poses, self._partners = None, {}        # for copy_draw='scan', on first use
        self.clouds, self.trees, index = [], [], []
        for s, path in enumerate(scan_paths):
            pts = load_scan(path, voxel)
            tree = KDTree(pts)
            kp = patches.uniform_keypoints(pts, keypoint_leaf)
            support = tree.query_radius(pts[kp], radius, count_only=True) - 1
            kp = kp[support >= min_points]
            self.clouds.append(pts)
            self.trees.append(tree)
            index.extend((s, k) for k in kp)
        if not index:
            raise ValueError(f"no keypoint with ≥ {min_points} neighbours within {radius} in "
                             f"{len(scan_paths)} scan(s)")
        index = np.array(index, np.int64)
        order = np.random.default_rng(seed).permutation(len(index))
        n_val = int(round(val_fraction * len(index))) if len(index) > 1 else 0
        self.splits = {"val": index[order[:n_val]], "train": index[order[n_val:]]}
        self.weights = None if weights is None else np.asarray(weights, np.float64)
        if self.weights is not None:
            groups = np.asarray(groups, np.int64)
            self.by_group = {k: [v[groups[v[:, 0]] == g] for g in range(len(self.weights))]
                             for k, v in self.splits.items()}
            empty = [g for g, w in enumerate(self.weights)
                     if w > 0 and len(self.by_group["train"][g]) == 0]
            if empty:
                raise ValueError(f"data.root entries {empty} have a weight but no keypoint")

    def __len__(self):
        return len(self.splits["train"])

    def statement(self):
        """What this source trains on, for the bundle: scans per folder, keypoints per split,
        and the evaluation scenes among them (empty unless a run was allowed them)."""
        folders = {}
        for path in self.scan_paths:
            folder = scan_folder_label(path)
            folders[folder] = folders.get(folder, 0) + 1
        return {"kind": "scans", "folders": folders,
                "keypoints": {k: int(len(v)) for k, v in self.splits.items()},
                "evaluation_scenes": evaluation_scenes.scenes_of(
                    list(self.scan_paths) + list(folders))}

    def draw(self, rng: np.random.Generator, batch_size, split="train"):
        """``[B, 2]`` (scan, point index) keypoints of one batch of ``split``."""
        pool = self.splits[split]
        if len(pool) == 0:
            raise ValueError(f"the {split!r} split is empty")
        if self.weights is None:
            return pool[rng.integers(0, len(pool), batch_size)]
        pools = self.by_group[split]
        w = np.array([wg if len(p) else 0.0 for wg, p in zip(self.weights, pools)])
        g = rng.choice(len(w), batch_size, p=w / w.sum())
        return np.stack([pools[k][rng.integers(len(pools[k]))] for k in g])

    def batch(self, step, batch_size, split="train", copies=False, occlusion=True,
              copy_draw="patch", copy_jitter=0.0):
        """``{'patches': [B, N, 3]}`` in units of the radius; with ``copies``, also
        ``'copies'`` (each patch rotated by ``'rotations'`` [B, 3, 3], occluded, resampled:
        :func:`rotated_copies`). ``copy_draw``: what a copy is made of — ``'patch'`` the
        patch's own points (the seed's), ``'support'`` a second, independent draw of N points
        from the keypoint's whole support, as a second scan samples the same surface
        differently, ``'scan'`` the same surface point in another scan of its scene (ground
        truth poses, :mod:`~sphere_jax.data.poses`; a second draw where no other scan sees
        it)."""
        checks.choice(copy_draw, "copy_draw", COPY_DRAWS)
        rng = np.random.default_rng([self.seed, step, 0 if split == "train" else 1])
        picks = self.draw(rng, batch_size, split)
        out = self._patches(picks, rng)
        result = {"patches": out}
        if copies:
            turns = None
            if copy_draw == "scan":
                base, turns = self._other_scan_patches(picks, rng)
            else:
                base = out if copy_draw == "patch" else self._patches(picks, rng)
            result.update(rotated_copies(base, rng, occlusion, copy_jitter, turns))
        return result

    def _other_scan_patches(self, picks, rng):
        """Patches ``[B, N, 3]`` of each picked point as another scan of its scene sees it, and
        the rotations ``[B, 3, 3]`` from each patch's frame to that scan's (identity, and a
        second draw from the keypoint's own support, where no other scan sees the point)."""
        if self._poses is None:
            self._poses = poses.scene_poses(self.scan_paths)
        pose = self._poses[1]
        out = self._patches(picks, rng)
        turns = np.broadcast_to(np.eye(3, dtype=np.float32), (len(picks), 3, 3)).copy()
        for b, (s, k) in enumerate(picks):
            others = self._scans_seeing(s, k)
            if not len(others):
                continue
            t = others[rng.integers(len(others))]
            rel = poses.relative(pose, s, t)
            centre = poses.transform(self.clouds[s][k], rel)
            got = patches.patches_around(self.clouds[t], centre[None], self.radius,
                                         self.n_points, rng, self.min_points, self.trees[t])
            if got.valid[0]:
                out[b], turns[b] = got.points[0] / self.radius, rel[:3, :3]
        return out, turns

    def _scans_seeing(self, s, k):
        """The other scans of scan s's scene with a point within 2 voxels of its point k."""
        if s not in self._partners:
            scene, pose = self._poses
            kps = np.unique(np.concatenate([v[v[:, 0] == s, 1] for v in self.splits.values()]))
            others = [t for t in np.flatnonzero(scene == scene[s]) if t != s] \
                if scene[s] >= 0 else []
            seen = np.zeros((len(kps), len(others)), bool)
            for c, t in enumerate(others):
                moved = poses.transform(self.clouds[s][kps], poses.relative(pose, s, t))
                seen[:, c] = self.trees[t].query(moved, k=1)[0][:, 0] < 2 * self.voxel
            self._partners[s] = (kps, np.asarray(others, np.int64), seen)
        kps, others, seen = self._partners[s]
        row = np.searchsorted(kps, k)
        return others[seen[row]] if row < len(kps) and kps[row] == k else others[:0]

    def _patches(self, picks, rng):
        out = np.empty((len(picks), self.n_points, 3), np.float32)
        for s in np.unique(picks[:, 0]):
            rows = np.nonzero(picks[:, 0] == s)[0]
            got = patches.extract_patches(self.clouds[s], picks[rows, 1], self.radius,
                                          self.n_points, rng, tree=self.trees[s])
            out[rows] = got.points / self.radius
        return out


COPY_DRAWS = ("patch", "support", "scan")


def rotated_copies(patches_BxNx3, rng: np.random.Generator, occlusion=True, jitter=0.0,
                   turns_Bx3x3=None):
    """Each unit patch rotated by a random rotation, occluded (seed 3.1.5), resampled to N
    points and, with ``jitter`` > 0, moved by Gaussian noise of that std (units of the radius):
    ``{'copies': [B, N, 3], 'rotations': [B, 3, 3]}`` — Compass's training pairs. With
    ``turns_Bx3x3`` the patches are already turned by those rotations from the frame the
    network's other input is in (copies from another scan), and ``'rotations'`` include them."""
    if not np.isfinite(jitter) or jitter < 0:
        raise checks.InputError("copy_jitter", "a finite number >= 0", repr(jitter))
    b, n, _ = patches_BxNx3.shape
    rots = augment.random_rotations(rng, b)
    cop = np.empty_like(patches_BxNx3)
    for k in range(b):
        rotated = augment.rotate(patches_BxNx3[k], rots[k])
        if occlusion:
            rotated = augment.occlude(rotated, 1.0, rng)
        cop[k] = augment.resample(rotated, n, rng)
        if jitter:
            cop[k] = augment.jitter(cop[k], jitter, rng)
    if turns_Bx3x3 is not None:
        rots = rots @ turns_Bx3x3
    return {"copies": cop, "rotations": rots.astype(np.float32)}


HOLDOUT_EVERY = 5     # every 5th shape of each class tested, every 5th of the rest validates


class ShapeSource:
    """A labelled shape set in one of ModelNet40's released layouts:

    * resampled (``modelnet40_normal_resampled``): ``shape_names.txt`` (or
      ``modelnet40_shape_names.txt``), ``train.txt`` / ``test.txt`` (or ``modelnet40_*.txt``)
      lists and ``<class>/<id>.txt`` files — also the embedded synthetic set;
    * original meshes: ``<class>/{train,test}/*.off``, each sampled to 10 000 surface points
      (seeded) and scaled into the unit sphere;
    * PointNet's HDF5: ``*train*.h5`` / ``*test*.h5`` (needs h5py) with ``shape_names.txt``.
    """

    def __init__(self, root, n_points, seed=0, holdout_every=HOLDOUT_EVERY,
                 val_every=HOLDOUT_EVERY):
        """Three disjoint splits, the same for every shape task: ``test`` is the set's own test
        split where it has one, else every ``holdout_every``-th shape of each class in file
        order (e.g. ModelNet40's train-only HDF5 release); ``val`` (checkpoints and settings
        are chosen on it) is every ``val_every``-th of each class's remaining shapes;
        ``train`` the rest."""
        self.n_points, self.seed = n_points, seed
        root = str(root)
        if not os.path.isdir(root):
            raise checks.MissingError(f"shape root {root!r} is not a folder")
        names = next((os.path.join(root, f) for f in ("shape_names.txt",
                                                      "modelnet40_shape_names.txt")
                      if os.path.isfile(os.path.join(root, f))), None)
        if glob.glob(os.path.join(root, "*.h5")):
            self.classes, splits = _load_h5(root, names)
        elif names is not None:
            self.classes, splits = _load_resampled(root, names)
        elif glob.glob(os.path.join(root, "*", "train", "*.off")):
            self.classes, splits = _load_off(root, seed)
        else:
            raise checks.MissingError(f"{root!r} holds no ModelNet layout (shape_names.txt with "
                                    f".txt shapes, <class>/train/*.off meshes, or *.h5 files)")
        if not splits["train"][0]:
            raise ValueError(f"no training shapes found under {root!r}")
        self.test_rule = None
        if not splits["test"][0]:
            splits["train"], splits["test"] = every_kth(*splits["train"], holdout_every,
                                                        "holdout_every")
            self.test_rule = int(holdout_every)
        splits["train"], splits["val"] = every_kth(*splits["train"], val_every, "val_every")
        self.val_every = int(val_every)
        self.splits = splits
        self.root = os.path.abspath(root)
        self.orientation = None       # how data/oriented.py turned the shapes, if it did

    def statement(self):
        """What this source trains on, for the bundle: the shape folder, shapes per split."""
        return {"kind": "shapes", "folders": {paths.portable(self.root):
                                              len(self.splits["train"][0])},
                "classes": len(self.classes),
                "shapes": {k: len(v[0]) for k, v in self.splits.items()},
                "splits": self.split_rule(),
                **({"orientation": self.orientation} if self.orientation else {})}

    def split_rule(self):
        """The splits in words, for the bundle's statement and the results."""
        test = ("the set's own test split" if self.test_rule is None else
                f"every {self.test_rule}th shape of each class in file order")
        return (f"test: {test}; val: every {self.val_every}th of each class's other shapes; "
                f"train: the rest")

    def batch(self, step, batch_size, split="train", rotate=False, copies=False,
              occlusion=True):
        """``{'points': [B, N, 3], 'labels': [B]}`` (``rotate``: each shape randomly rotated);
        with ``copies``, Compass's training batch on whole shapes instead: ``'patches'`` (unit
        shapes), ``'copies'`` and ``'rotations'``."""
        shapes, labels = self.splits[split]
        if not shapes:
            raise ValueError(f"the {split!r} split of the shape set is empty")
        rng = np.random.default_rng([self.seed, step, 0 if split == "train" else 1])
        pick = rng.integers(0, len(shapes), batch_size)
        pts = np.stack([shapes[i][rng.choice(len(shapes[i]), self.n_points,
                                             replace=len(shapes[i]) < self.n_points)]
                        for i in pick]).astype(np.float32)
        if copies:
            unit = patches.unit_shapes(pts)[0]
            return {"patches": unit, **rotated_copies(unit, rng, occlusion)}
        if rotate:
            pts = np.einsum("bij,bnj->bni", augment.random_rotations(rng, batch_size), pts)
        return {"points": pts.astype(np.float32), "labels": labels[pick]}


def every_kth(shapes, labels, every, name="every"):
    """``(kept, held)`` ``(shapes, labels)`` pairs from one labelled list: the k-th, 2k-th, ...
    shape of each class (in list order) is held, the rest kept; a class with fewer than k
    shapes keeps them all."""
    if int(every) != every or every < 2:
        raise ValueError(f"{name} must be an integer ≥ 2, got {every!r}")
    rank = np.zeros(len(labels), np.int64)
    seen = {}
    for i, c in enumerate(labels):
        seen[c] = seen.get(c, 0) + 1
        rank[i] = seen[c]
    held = (rank % int(every) == 0)
    pick = lambda m: ([s for s, t in zip(shapes, m) if t], np.asarray(labels)[m])
    return pick(~held), pick(held)


def _load_resampled(root, names_file):
    classes = open(names_file).read().split()
    splits = {}
    for split in ("train", "test"):
        lst = next((os.path.join(root, f) for f in (f"{split}.txt", f"modelnet40_{split}.txt")
                    if os.path.isfile(os.path.join(root, f))), None)
        shapes, labels = [], []
        for sid in (open(lst).read().split() if lst else []):
            cls = sid.rsplit("_", 1)[0]
            path = os.path.join(root, cls, sid + ".txt")
            if os.path.isfile(path):
                shapes.append(io.read_modelnet_txt(path).points)
                labels.append(classes.index(cls))
        splits[split] = (shapes, np.array(labels, np.int64))
    return classes, splits


def _load_off(root, seed, n_surface=10_000):
    classes = sorted(d for d in os.listdir(root)
                     if os.path.isdir(os.path.join(root, d, "train")))
    splits = {}
    for split in ("train", "test"):
        shapes, labels = [], []
        for c, cls in enumerate(classes):
            for k, path in enumerate(sorted(glob.glob(os.path.join(root, cls, split, "*.off")))):
                rng = np.random.default_rng([seed, c, k, split == "test"])
                pts = io.sample_mesh(io.read_off(path), n_surface, rng).points
                pts = pts - (pts.min(0) + pts.max(0)) / 2
                shapes.append(pts / max(float(np.linalg.norm(pts, axis=1).max()), 1e-12))
                labels.append(c)
        splits[split] = (shapes, np.array(labels, np.int64))
    return classes, splits


def _load_h5(root, names_file):
    splits = {}
    for split in ("train", "test"):
        shapes, labels = [], []
        for path in sorted(glob.glob(os.path.join(root, f"*{split}*.h5"))):
            data, lab, _ = io.read_modelnet_h5(path)
            shapes += list(data)
            labels += lab.tolist()
        splits[split] = (shapes, np.array(labels, np.int64))
    n_classes = int(max(splits["train"][1].max(initial=-1), splits["test"][1].max(initial=-1))) + 1
    classes = open(names_file).read().split() if names_file else [str(k) for k in
                                                                   range(n_classes)]
    return classes, splits


# ---- packed scans: the training data, voxelised once, for another machine -------------------

PACK_INDEX = "SOURCE.json"


def scan_folder_label(path):
    """What a scan's folder is, for a bundle's statement of its training data: the portable
    folder (:func:`sphere_jax.paths.portable`), the RGB-D sequence a fused fragment came from,
    or, for a packed scan, the folder it was packed from."""
    index = _pack_index(os.path.dirname(path))
    if index is not None:
        return index["scans"][os.path.basename(path)] + f" (packed at {index['voxel']} m)"
    rgbd_folder = fusion.fused_source(os.path.dirname(path))
    return (paths.portable(rgbd_folder) + " (fused RGB-D)" if rgbd_folder
            else paths.portable(os.path.dirname(path)))


def load_scan(path, voxel):
    """Points ``[N, 3]`` of a scan on the ``voxel`` grid (a scan packed at that voxel as is)."""
    index = _pack_index(os.path.dirname(path))
    pts = io.read_points(path).points
    if index is not None and float(index["voxel"]) == float(voxel):
        return pts.astype(np.float32)
    return patches.voxel_downsample(pts, voxel)


def pack_scans(roots, voxel, out_dir):
    """Write each entry of ``roots`` (a ``data.root`` list) voxelised at ``voxel`` as binary PLY
    scans in ``out_dir/<k>-<name>/``, with a ``SOURCE.json`` naming each scan's origin; the
    pack's folders, in the same order, are a ``data.root`` that trains on the same keypoints
    without open3d, the RGB-D fusion or the renderer (the embedded rooms: 164 MB rendered,
    a tenth of it packed). Returns ``{folder: scans}``."""
    names = root_entries(roots)
    voxel = checks.positive(voxel, "voxel")
    written = {}
    for k, (name, group) in enumerate(zip(names, scan_groups(roots))):
        slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", os.path.basename(name.rstrip("/")) or name)
        folder = workdirs.prepare(os.path.join(out_dir, f"{k}-{slug}"), "out_dir")
        index = {"entry": name, "voxel": voxel, "scans": {}}
        for i, path in enumerate(group):
            file = f"scan_{i:03d}.ply"
            ply.write_ply(os.path.join(folder, file), load_scan(path, voxel))
            index["scans"][file] = scan_folder_label(path)
        io.atomic_write(os.path.join(folder, PACK_INDEX), json.dumps(index, indent=1).encode())
        written[folder] = len(group)
    return written


def packed_folders(roots, pack):
    """The folders of the pack ``pack`` (:func:`pack_scans`) that hold the entries of
    ``roots``, in their order: the same data.root read on a machine without the renderer,
    open3d or the real scans (:class:`~sphere_jax.checks.ConfigError` for a pack that is not
    there or lacks an entry, naming it)."""
    if not os.path.isdir(str(pack)):
        raise checks.ConfigError("config.train.pack", "a folder made by python -m "
                                 "experiments.make_data --pack=ROOTS --out=DIR", pack)
    held = {}
    for index in sorted(glob.glob(os.path.join(str(pack), "*", PACK_INDEX))):
        folder = os.path.dirname(index)
        held.setdefault(_pack_index(folder).get("entry"), folder)
    missing = [e for e in root_entries(roots) if e not in held]
    if missing:
        raise checks.ConfigError(f"config.train.pack {str(pack)!r} holds no pack of the "
                                 f"data.root entries {missing} (it holds "
                                 f"{sorted(map(str, held))})")
    return [held[e] for e in root_entries(roots)]


def _pack_index(folder):
    path = os.path.join(folder, PACK_INDEX)
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return json.load(f)
