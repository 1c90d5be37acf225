"""Compass's and the descriptors' training batches from scans: keypoints of every scan, split
into training and validation keypoints, and deterministic batches of unit-ball patches with,
for Compass, their rotated, occluded copies.

Batches are a pure function of ``(seed, step)``: a resumed run sees exactly the batches the
uninterrupted run would have seen.
"""
from __future__ import annotations

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks
from sphere_jax.data import augment, held_out, patches, poses
from sphere_jax.data.scan_roots import load_scan, scan_folder_label


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
                "evaluation_scenes": held_out.scenes_of(
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
            result.update(augment.rotated_copies(base, rng, occlusion, copy_jitter, turns))
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
