"""How many frame hypotheses: Compass's strongest SO(3) modes (:mod:`sphere_jax.features.modes`)
scored on scan pairs with ground truth for h = 1 (Compass as it ships) and more.

* **frame recall**: the share of corresponding keypoints (the "perfect detector" of
  :mod:`repeatability`) where some hypothesis of one scan and some of the other are repeatable
  (both x̂ and ẑ within ρ = 0.97);
* **matching**: LEAD under the first h hypotheses, mutual nearest neighbours by the smallest
  distance over the h × h hypothesis pairs, scored as the registration benchmark scores them
  (inlier ratio and correct matches within τ1).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from tqdm.auto import tqdm

from sphere_jax.bundles import inference
from sphere_jax.eval import pair_sets as scene_lib
from sphere_jax.eval.repeatability import correspondences, repeatable
from sphere_jax.features import modes
from sphere_jax.registration.matching import mutual_matches


@dataclasses.dataclass
class PairResult:
    scene: str
    pair: tuple
    h: int
    frame_recall: float
    inlier_ratio: float
    correct: int
    matches: int


def frame_recall(frames_i_CxHx3x3, frames_j_CxHx3x3, rotation_3x3, h):
    """The share of correspondences (row c of each side) where one of the first ``h``
    hypotheses of i and one of j (turned by the ground-truth ``rotation``) are repeatable."""
    fi = frames_i_CxHx3x3[:, :h, None]                                  # [C, h, 1, 3, 3]
    fj = np.einsum("xy,chyz->chxz", rotation_3x3, frames_j_CxHx3x3[:, :h])[:, None]
    return float(repeatable(fi, fj).any(axis=(1, 2)).mean()) if len(fi) else float("nan")


def evaluate_pair(compass, frag_i, frag_j, t_gt, desc_i, desc_j, hs, radius, match_dist,
                  tau1):
    """One pair's :class:`PairResult` per number of hypotheses in ``hs``; ``desc_*`` are LEAD
    under each keypoint's ``max(hs)`` hypotheses ``[K, H, D]``."""
    ki, kj = correspondences(frag_i, frag_j, t_gt, match_dist)
    k = max(hs)
    fi, fj = (compass.orient_modes(f.points, idx, k, radius=radius, on_invalid="mask")[0]
              for f, idx in ((frag_i, ki), (frag_j, kj)))
    src = frag_i.points[frag_i.keypoints]
    dst = frag_j.points[frag_j.keypoints] @ t_gt[:3, :3].T + t_gt[:3, 3]
    out = []
    for h in hs:
        ia, ib = mutual_matches(desc_i[:, :h], desc_j[:, :h])
        correct = int((np.linalg.norm(src[ia] - dst[ib], axis=1) < tau1).sum())
        out.append(PairResult("", (), h, frame_recall(fi, fj, t_gt[:3, :3], h),
                              correct / max(len(ia), 1), correct, len(ia)))
    return out


def run(root, compass_path, lead_path, hs=(1, 2, 3, 4), radius=0.30, voxel=0.02,
        n_keypoints=2500, match_dist=None, tau1=0.10, seed=0, progress=True):
    """Every pair under ``root`` (3DMatch layout): a list of :class:`PairResult`."""
    match_dist = match_dist or voxel         # as eval_lrf: a point of j this close
    compass = inference.cached_bundle(compass_path)
    describe = modes.lead_modes(radius, {"lead": lead_path, "compass": compass_path},
                                k=max(hs))
    results = []
    for ps in scene_lib.find_pair_sets(root, voxel):
        frags = scene_lib.prepare_all(ps, seed=seed, voxel=voxel, n_keypoints=n_keypoints)
        desc = {key: describe([f])[0] for key, f in
                tqdm(frags.items(), desc=f"{ps.name}: LEAD under modes", disable=not progress)}
        for i, j in ps.pairs:
            for r in evaluate_pair(compass, frags[i], frags[j], ps.transforms[(i, j)],
                                   desc[i], desc[j], hs, radius, match_dist, tau1):
                results.append(dataclasses.replace(r, scene=ps.name, pair=(i, j)))
    return results
