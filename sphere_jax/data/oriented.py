"""Shapes turned into a whole-shape Compass's frames once, for the classifiers of the
rotation-invariant classification experiment (thesis 3.3).

Orienting is the costly part of a Compass + PointNet step (a spherical CNN per shape against a
PointNet), and a shape's frame does not change between epochs: each shape's frame is computed
once and kept in ``<cache>/oriented/<key>.npz`` (``paths.cache_root()``), keyed by the bundle's
fingerprint, the shape set, its split and the turns. Only the centres ``[S, 1, 3]`` and frames
``[S, 3, 3]`` are kept (seeded turns are drawn again); the shapes are turned again on load.

``orienter`` is anything with ``frames(shapes_BxNx3) -> (centres, frames)`` and a ``key``
(:class:`sphere_jax.bundles.inference.ShapeOrienter`).
"""
from __future__ import annotations

import copy
import hashlib
import io
import json
import os

import numpy as np
from tqdm import tqdm

from sphere_jax import files, paths
from sphere_jax.data import augment

CHUNK = 256          # shapes per call of the orienter


def seeded_turns(n, seed):
    """``n`` rotations uniform on SO(3) from ``seed`` ``[n, 3, 3]`` (float64)."""
    return augment.random_rotations(np.random.default_rng(seed), n)


def turn(shapes, turns_Sx3x3):
    """Each shape ``[N, 3]`` of the list turned by its rotation (``p ↦ R p``)."""
    return [np.asarray(s, np.float64) @ r.T for s, r in zip(shapes, turns_Sx3x3)]


def frames(orienter, shapes, what, progress=True):
    """``(centres [S, 1, 3], frames [S, 3, 3])`` of a list of shapes, from the cache when an
    earlier run computed them (``what``: a JSON-able description of the shapes that, with the
    orienter's key, names them)."""
    key = hashlib.sha256(json.dumps({"orienter": orienter.key, **what},
                                    sort_keys=True).encode()).hexdigest()[:20]
    path = os.path.join(paths.cache_root(), "oriented", key + ".npz")
    if os.path.isfile(path):
        with np.load(path) as kept:
            if len(kept["frames"]) == len(shapes):
                return kept["centres"], kept["frames"]
    centres = np.zeros((len(shapes), 1, 3), np.float64)
    out = np.zeros((len(shapes), 3, 3), np.float32)
    by_size = {}                      # the orienter takes shapes of one point count per call
    for i, s in enumerate(shapes):
        by_size.setdefault(len(s), []).append(i)
    bar = tqdm(total=len(shapes), desc=f"orienting {what.get('split', 'shapes')}",
               disable=not progress, leave=False)
    for idx in by_size.values():
        for k in range(0, len(idx), CHUNK):
            part = idx[k:k + CHUNK]
            centres[part], out[part] = orienter.frames(np.stack([shapes[i] for i in part]))
            bar.update(len(part))
    bar.close()
    os.makedirs(os.path.dirname(path), exist_ok=True)
    buffer = io.BytesIO()
    np.savez(buffer, centres=centres, frames=out)
    files.atomic_write(path, buffer.getvalue())
    return centres, out


def apply(shapes, centres, frames_Sx3x3):
    """Each shape in its frame: ``(p − c) @ F`` (float32)."""
    return [((np.asarray(s, np.float64) - c) @ f).astype(np.float32)
            for s, c, f in zip(shapes, centres, frames_Sx3x3)]


def oriented_source(source, orienter, rotated_copies=0, seed=0, progress=True):
    """A copy of the :class:`~sphere_jax.data.shape_source.ShapeSource` ``source`` whose shapes,
    in every split, are in ``orienter``'s frames. ``rotated_copies`` = k > 0: the training split
    instead holds k copies of each shape, each turned by a seeded random rotation before it is
    oriented (the classifier then learns the frames Compass gives turned shapes, its mistakes
    and its choices among a symmetric shape's frames included)."""
    out = copy.copy(source)
    out.splits = {}
    out.orientation = {"orienter": orienter.key, "rotated_copies": int(rotated_copies)}
    for split, (shapes, labels) in source.splits.items():
        what = {"root": source.root, "split": split, "rule": source.split_rule(),
                "shapes": len(shapes)}
        if split == "train" and rotated_copies:
            turns = seeded_turns(rotated_copies * len(shapes), [seed, 1])
            shapes = turn([s for s in shapes for _ in range(rotated_copies)], turns)
            labels = np.repeat(labels, rotated_copies)
            what.update(rotated_copies=int(rotated_copies), seed=int(seed))
        out.splits[split] = (apply(shapes, *frames(orienter, shapes, what, progress)), labels)
    return out
