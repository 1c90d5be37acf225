"""Pair frames voted from a first pass of matches (the rotation vote of YOHO, Wang et al. 2022).

An LRF-based descriptor is matched once in its own LRFs. Every mutual match (a in scan i, b in
scan j) proposes the pair's rotation ``R = F_a F_bᵀ`` (frames hold the axes as columns, so a
neighbour's local coordinates are ``Fᵀ (p − k)``, and a repeatable LRF has ``F_a = R F_b``).
The proposals of correct matches agree, those of wrong ones scatter over SO(3): the mode — the
proposal with the most others within ``tol_deg``, refined by the chordal mean of those — is
the pair's rotation R̂. Both scans are then described again, scan i in the identity frame and
scan j in R̂ᵀ: what :class:`~sphere_jax.eval.methods.GroundTruthFrames` does with the ground
truth, with R̂ read from the two scans alone.

It stays rotation-invariant: turning scan j by Q turns its LRFs by Q, so R̂ becomes R̂ Qᵀ and
scan j's second frame Q R̂ᵀ turns with it. It serves any LRF-based descriptor; ``lead_vote``
(LEAD, first pass in Compass's frames) and ``shot_vote`` (SHOT in its LRF) are the two the
benchmark runs, so that the vote's gain is measured for both sides of the comparison.

A vote can be wrong (at low overlap a structure both scans share can outvote the few correct
matches); RANSAC's consensus then decides which pass to keep (:meth:`VotedFrames.describe_pairs`).
"""
from __future__ import annotations

import dataclasses
from typing import Callable, NamedTuple

import jax
import numpy as np

from sphere_jax import api
from sphere_jax.eval import descriptors, lrfs
from sphere_jax.eval import methods as method_lib
from sphere_jax.models import lead as lead_model

TOL_DEG = 10.0


class Vote(NamedTuple):
    rotation: np.ndarray     # [3, 3] R̂ with p_i ≈ R̂ p_j + t
    support: int             # proposals within tol_deg of R̂
    proposals: int           # finite proposals (one per first-pass match)
    second_pass: bool = True  # False: the first pass's matches agreed more, and were kept


def project_to_rotation(m_3x3):
    """The rotation nearest to ``m`` in the Frobenius norm (SVD, determinant forced to +1)."""
    u, _, vt = np.linalg.svd(np.asarray(m_3x3, np.float64))
    return u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt


def vote_rotation(frames_a_Mx3x3, frames_b_Mx3x3, tol_deg=TOL_DEG, rows=1024) -> Vote:
    """The mode of the proposals ``F_a[m] F_b[m]ᵀ`` of M matched frame pairs. Two rotations are
    within θ of each other when ``tr(AᵀB) = Σ A∘B > 1 + 2 cos θ``: one ``[rows, M]`` matmul of
    the flattened proposals per block counts every proposal's neighbours. Non-finite frames
    (keypoints an LRF could not orient) propose nothing; with no proposal the vote is the
    identity with support 0."""
    fa, fb = np.asarray(frames_a_Mx3x3, np.float64), np.asarray(frames_b_Mx3x3, np.float64)
    if fa.ndim != 3 or fa.shape[1:] != (3, 3) or fa.shape != fb.shape:
        raise ValueError(f"frames_a and frames_b must both be [M, 3, 3], got {fa.shape} and "
                         f"{fb.shape}")
    if not 0.0 < tol_deg < 180.0:
        raise ValueError(f"tol_deg must be in (0, 180) degrees, got {tol_deg}")
    proposals = np.einsum("mij,mkj->mik", fa, fb)
    proposals = proposals[np.all(np.isfinite(proposals), axis=(1, 2))]
    if len(proposals) == 0:
        return Vote(np.eye(3), 0, 0)
    flat = proposals.reshape(-1, 9)
    trace_min = 1.0 + 2.0 * np.cos(np.radians(tol_deg))
    counts = np.concatenate([(flat[s:s + rows] @ flat.T > trace_min).sum(1)
                             for s in range(0, len(flat), rows)])
    rotation = proposals[int(np.argmax(counts))]
    for _ in range(2):                       # the mean of the mode's neighbours, twice
        near = flat @ rotation.ravel() > trace_min
        if not near.any():                   # a mean that drifted from every proposal
            break
        rotation = project_to_rotation(proposals[near].mean(0))
    support = int((flat @ rotation.ravel() > trace_min).sum())
    return Vote(rotation, support, len(proposals))


@dataclasses.dataclass(frozen=True)
class VotedFrames:
    """A descriptor with the pair vote: ``first(fragment) -> (descriptors [K, D], frames
    [K, 3, 3], state)`` once per scan (its own LRFs; NaN frames where it has none) and
    ``again(fragment, state, rotation_3x3) -> [K, D]``, the scan described with every keypoint
    in one frame."""
    first: Callable
    again: Callable
    tol_deg: float = TOL_DEG

    def describe_pairs(self, frags: dict, pairs, match: Callable,
                       consensus: Callable | None = None, progress_bar=lambda items: items):
        """``({(i, j): (desc_i, desc_j)}, {(i, j): Vote})`` for the scans ``frags`` (key ->
        Fragment) and the pairs ``(i, j)``, the first pass matched by ``match(desc_i, desc_j)
        -> (ia, ib)`` (the benchmark's mutual nearest neighbours); each scan's first pass is
        computed once.

        A vote can be wrong — at low overlap the few correct matches may be outvoted by a
        structure both scans share (a floor, a wall corner) — and descriptors in a wrong frame
        match nothing. With ``consensus(frag_i, frag_j, desc_i, desc_j) -> int`` (how many
        matches one rigid transform explains: RANSAC's inliers) the pass that more matches
        agree with is kept, a choice made from the scans alone."""
        cache, inputs, votes = {}, {}, {}
        for i, j in progress_bar(list(pairs)):
            for k in (i, j):
                if k not in cache:
                    cache[k] = self.first(frags[k])
            (d_i, f_i, s_i), (d_j, f_j, s_j) = cache[i], cache[j]
            ia, ib = match(d_i, d_j)
            vote = vote_rotation(f_i[ia], f_j[ib], self.tol_deg)
            second = (self.again(frags[i], s_i, np.eye(3)),
                      self.again(frags[j], s_j, vote.rotation.T))
            if consensus is not None and (consensus(frags[i], frags[j], d_i, d_j) >
                                          consensus(frags[i], frags[j], *second)):
                vote, second = vote._replace(second_pass=False), (d_i, d_j)
            votes[(i, j)], inputs[(i, j)] = vote, second
        return inputs, votes


def _shot_vote(radius):
    def first(f):
        nb = method_lib.neighbourhoods(f, f.keypoints, radius)
        frames = lrfs.shot_lrf(nb)
        return descriptors.shot(nb, f.normals, frames), frames, None

    def again(f, _, rotation_3x3):
        # The supports are found again rather than kept: a scene's scans would hold them all.
        nb = method_lib.neighbourhoods(f, f.keypoints, radius)
        return descriptors.shot(nb, f.normals, method_lib.one_frame(rotation_3x3,
                                                                     len(f.keypoints)))
    return first, again


def _lead_vote(radius, bundles, chunk):
    lead = api.cached_bundle(bundles["lead"])
    compass = api.cached_bundle(bundles["compass"])
    turn = jax.jit(lead_model.canonical_descriptors)

    def turned(maps_KxD, frames_Kx3x3):
        side = round(maps_KxD.shape[1] ** (1 / 3))
        cubes = maps_KxD.reshape(len(maps_KxD), side, side, side)
        return api.stream_chunked(turn, lambda a, b: (cubes[a:b], frames_Kx3x3[a:b]),
                                  len(cubes), chunk)

    def first(f):
        k = len(f.keypoints)
        # LEAD's SO(3) maps in the scan's own axes, computed once: every frame after this is
        # a spectral turn of them, not another pass of the network.
        maps, valid = lead.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                    frames=method_lib.one_frame(np.eye(3), k),
                                    on_invalid="mask")
        maps[~valid] = 0
        frames, oriented = compass.orient(f.points, f.keypoints, radius=radius, chunk=chunk,
                                          on_invalid="mask")
        frames[~oriented] = np.eye(3)
        desc = turned(maps, frames) if k else maps
        frames[~(valid & oriented)] = np.nan          # no proposal from an undescribed keypoint
        return desc, frames, maps

    def again(f, maps, rotation_3x3):
        if np.allclose(rotation_3x3, np.eye(3)) or not len(maps):
            return maps
        return turned(maps, method_lib.one_frame(rotation_3x3, len(maps)))
    return first, again


def voted_frames(name, radius, bundles=None, chunk=None, tol_deg=TOL_DEG) -> VotedFrames:
    """``lead_vote`` or ``shot_vote`` (:data:`~sphere_jax.eval.methods.VOTED`) with supports of
    ``radius`` metres; ``bundles`` maps lead and compass to bundle paths."""
    bundles = bundles or {}
    if name not in method_lib.VOTED:
        raise ValueError(f"unknown voted method {name!r}; choose from "
                         f"{', '.join(method_lib.VOTED)}")
    if method_lib.bundles_needed([name], bundles):
        raise ValueError(f"method {name!r} needs bundle(s) {method_lib.BUNDLE_OF[name]} in "
                         f"'bundles'")
    first, again = (_shot_vote(radius) if name == "shot_vote" else
                    _lead_vote(radius, bundles, chunk))
    return VotedFrames(first, again, tol_deg)
