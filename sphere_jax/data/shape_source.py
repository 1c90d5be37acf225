"""Labelled shape sets (ModelNet40's released layouts and the embedded synthetic set) in three
disjoint splits, and deterministic batches of them: the classifiers' batches and Compass's on
whole shapes.

Batches are a pure function of ``(seed, step)``, as the scans' are
(:mod:`sphere_jax.data.patch_source`).
"""
from __future__ import annotations

import glob
import os

import numpy as np

from sphere_jax import checks, paths
from sphere_jax.data import augment, patches
from sphere_jax.data.readers import io


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
            return {"patches": unit, **augment.rotated_copies(unit, rng, occlusion)}
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
