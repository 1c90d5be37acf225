"""Pair frames voted from a first pass of matches (the rotation vote of YOHO, Wang et al. 2022).

An LRF-based descriptor is matched once in its own LRFs. Every mutual match (a in scan i, b in
scan j) proposes the pair's rotation ``R = F_a F_bᵀ`` (frames hold the axes as columns, so a
neighbour's local coordinates are ``Fᵀ (p − k)``, and a repeatable LRF has ``F_a = R F_b``).
The proposals of correct matches agree, those of wrong ones scatter over SO(3): the mode — the
proposal with the most others within ``tol_deg``, refined by the chordal mean of those — is
the pair's rotation R̂. Both scans are then described again, scan i in the identity frame and
scan j in R̂ᵀ: what :class:`~sphere_jax.features.methods.GroundTruthFrames` does with the ground
truth, with R̂ read from the two scans alone.

It stays rotation-invariant: turning scan j by Q turns its LRFs by Q, so R̂ becomes R̂ Qᵀ and
scan j's second frame Q R̂ᵀ turns with it. Turning scan i turns both scans' second-pass
descriptors by one rotation, which leaves distances unchanged only in coordinates where a turn
is orthogonal: LEAD's whitened maps are (:func:`~sphere_jax.bundles.whitening.
rotation_averaged`), its raw grid values are not (their distances move by up to 16 %). It serves
any LRF-based descriptor (:class:`VotedFrames` takes the two passes as functions);
:mod:`sphere_jax.features.voted` makes ``lead_vote`` (LEAD, first pass in Compass's frames) and
``shot_vote`` (SHOT in its LRF), so that the vote's gain is measured for both sides of the
comparison.

A vote can be wrong: at low overlap a structure both scans share can outvote the few correct
matches, and in an axis-aligned room an LRF that swaps a patch's axes the same way everywhere
(Compass does) makes a symmetry of the room's box the strongest mode. So the candidates are
the vote's strongest modes and the 24 box turns of the first (:func:`box_orbit`, the box being
the scan's Manhattan frame); RANSAC's consensus on each candidate's second pass, and on the
first pass, decides which to keep (:meth:`VotedFrames.describe_pairs`).
"""
from __future__ import annotations

import dataclasses
import itertools
from typing import Callable, NamedTuple

import numpy as np

TOL_DEG = 10.0
HYPOTHESES = 5


class Vote(NamedTuple):
    rotation: np.ndarray     # [3, 3] R̂ with p_i ≈ R̂ p_j + t
    support: int             # proposals within tol_deg of R̂
    proposals: int           # finite proposals (one per first-pass match)
    second_pass: bool = True  # False: the first pass's matches agreed more, and were kept
    mode: int = 0            # which of the vote's modes this is (0: the strongest)
    box_turn_deg: float = 0.0  # the box symmetry applied to that mode (0: none; box_orbit)


def project_to_rotation(m_3x3):
    """The rotation nearest to ``m`` in the Frobenius norm (SVD, determinant forced to +1)."""
    u, _, vt = np.linalg.svd(np.asarray(m_3x3, np.float64))
    return u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt


def _proposals(frames_a_Mx3x3, frames_b_Mx3x3):
    """``[M', 3, 3]``: the finite proposals ``F_a[m] F_bᵀ[m]`` of matched frame pairs."""
    proposals = np.einsum("mij,mkj->mik", frames_a_Mx3x3, frames_b_Mx3x3)
    return proposals[np.all(np.isfinite(proposals), axis=(1, 2))]


def vote_rotation(frames_a_Mx3x3, frames_b_Mx3x3, tol_deg=TOL_DEG, rows=1024) -> Vote:
    """The strongest mode of the proposals (:func:`vote_rotations` with one hypothesis)."""
    return vote_rotations(frames_a_Mx3x3, frames_b_Mx3x3, tol_deg, 1, rows)[0]


def vote_rotations(frames_a_Mx3x3, frames_b_Mx3x3, tol_deg=TOL_DEG, hypotheses=1,
                   rows=1024) -> list[Vote]:
    """Up to ``hypotheses`` modes of the proposals ``F_a[m] F_bᵀ[m]`` of M matched frame pairs,
    strongest first. Two rotations are within θ of each other when ``tr(AᵀB) = Σ A∘B >
    1 + 2 cos θ``: one ``[rows, M]`` matmul of the flattened proposals per block counts every
    proposal's neighbours; the proposal with the most is refined twice by the chordal mean of
    them. Each later mode is sought among the proposals farther than ``2 tol_deg`` from every
    mode before it.

    Why more than one: an LRF that swaps a patch's axes the same way across a scene (Compass
    in an axis-aligned room) makes a box symmetry of the true rotation the strongest mode; the
    true one is then a weaker mode, which RANSAC's consensus can pick out
    (:meth:`VotedFrames.describe_pairs`). Non-finite frames (keypoints an LRF could not
    orient) propose nothing; with no proposal the vote is the identity with support 0."""
    fa, fb = np.asarray(frames_a_Mx3x3, np.float64), np.asarray(frames_b_Mx3x3, np.float64)
    if fa.ndim != 3 or fa.shape[1:] != (3, 3) or fa.shape != fb.shape:
        raise ValueError(f"frames_a and frames_b must both be [M, 3, 3], got {fa.shape} and "
                         f"{fb.shape}")
    if not 0.0 < tol_deg < 90.0:
        raise ValueError(f"tol_deg must be in (0, 90) degrees, got {tol_deg}")
    if int(hypotheses) != hypotheses or hypotheses < 1:
        raise ValueError(f"hypotheses must be a positive integer, got {hypotheses!r}")
    proposals = _proposals(fa, fb)
    if len(proposals) == 0:
        return [Vote(np.eye(3), 0, 0)]
    flat = proposals.reshape(-1, 9)
    trace_min = 1.0 + 2.0 * np.cos(np.radians(tol_deg))
    trace_apart = 1.0 + 2.0 * np.cos(np.radians(2.0 * tol_deg))
    alive, votes = np.ones(len(flat), bool), []
    while len(votes) < hypotheses and alive.any():
        idx = np.flatnonzero(alive)
        live = flat[idx]
        counts = np.concatenate([(live[s:s + rows] @ live.T > trace_min).sum(1)
                                 for s in range(0, len(live), rows)])
        rotation = proposals[idx[int(np.argmax(counts))]]
        for _ in range(2):                   # the mean of the mode's neighbours, twice
            near = alive & (flat @ rotation.ravel() > trace_min)
            if not near.any():               # a mean that drifted from every proposal
                break
            rotation = project_to_rotation(proposals[near].mean(0))
        closeness = flat @ rotation.ravel()
        votes.append(Vote(rotation, int((alive & (closeness > trace_min)).sum()),
                          len(proposals)))
        alive &= closeness <= trace_apart
    return votes


def _box_rotations():
    """The 24 rotations of a cube onto itself (signed permutation matrices, det +1), the
    identity first."""
    out = [np.diag(signs) @ np.eye(3)[list(order)]
           for order in itertools.permutations(range(3))
           for signs in itertools.product((1.0, -1.0), repeat=3)]
    return np.stack(sorted((w for w in out if np.linalg.det(w) > 0),
                           key=lambda w: -np.trace(w)))


BOX_ROTATIONS = _box_rotations()              # [24, 3, 3]


def box_orbit(rotation_3x3, normals_Nx3) -> np.ndarray:
    """``[24, 3, 3]``: the rotations ``W R̂`` for the turns W of a box onto itself, the box's
    axes being scan i's Manhattan frame — the eigenvectors of its normals' second moment
    ``Σ n nᵀ``, diagonal in a room's axes when its surfaces face along them. The identity
    comes first.

    Why: in an axis-aligned room an LRF can swap a patch's axes the same way all over the
    scene (Compass does, measured on the embedded rooms), so the vote's strongest mode is the
    truth turned by such a W; the truth is then one of these 24."""
    n = np.asarray(normals_Nx3, np.float64)
    n = n[np.all(np.isfinite(n), axis=1)]
    if n.ndim != 2 or n.shape[1:] != (3,) or len(n) < 3:
        raise ValueError(f"normals must be [N, 3] with at least 3 finite rows, got "
                         f"{np.shape(normals_Nx3)}")
    _, axes = np.linalg.eigh(n.T @ n)
    return axes @ BOX_ROTATIONS @ axes.T @ np.asarray(rotation_3x3, np.float64)


@dataclasses.dataclass(frozen=True)
class VotedFrames:
    """A descriptor with the pair vote: ``first(fragment) -> (descriptors [K, D], frames
    [K, 3, 3], state)`` once per scan (its own LRFs; NaN frames where it has none) and
    ``again(fragment, state, rotation_3x3) -> [K, D]``, the scan described with every keypoint
    in one frame. ``hypotheses``: how many of the vote's modes a consensus may choose from;
    ``box``: whether the box symmetries of the strongest mode (:func:`box_orbit`) join them."""
    first: Callable
    again: Callable
    tol_deg: float = TOL_DEG
    hypotheses: int = HYPOTHESES
    box: bool = True

    def candidates(self, frames_a, frames_b, normals_a) -> list[Vote]:
        """The rotations a consensus chooses from: the vote's modes, then the box turns of
        the strongest that are not near one of them (each with its support among the
        proposals)."""
        modes = vote_rotations(frames_a, frames_b, self.tol_deg, self.hypotheses)
        if not self.box or modes[0].proposals == 0:
            return modes
        proposals = _proposals(frames_a, frames_b).reshape(-1, 9)
        near, apart = (1.0 + 2.0 * np.cos(np.radians(d)) for d in (self.tol_deg,
                                                                   2.0 * self.tol_deg))
        out = list(modes)
        for w, turned in zip(BOX_ROTATIONS[1:], box_orbit(modes[0].rotation, normals_a)[1:]):
            if max(np.sum(v.rotation * turned) for v in out) > apart:
                continue
            out.append(Vote(turned, int((proposals @ turned.ravel() > near).sum()),
                            modes[0].proposals, box_turn_deg=float(np.degrees(
                                np.arccos(np.clip((np.trace(w) - 1) / 2, -1, 1))))))
        return out

    def describe_pairs(self, frags: dict, pairs, match: Callable,
                       consensus: Callable | None = None, progress_bar=lambda items: items,
                       screen: Callable | None = None):
        """``({(i, j): (desc_i, desc_j)}, {(i, j): Vote})`` for the scans ``frags`` (key ->
        Fragment) and the pairs ``(i, j)``, the first pass matched by ``match(desc_i, desc_j)
        -> (ia, ib)`` (the benchmark's mutual nearest neighbours); each scan's first pass is
        computed once.

        A vote can be wrong — at low overlap the few correct matches may be outvoted by a
        structure both scans share (a floor, a wall corner), in a box-shaped room by a symmetry
        of the box — and descriptors in a wrong frame match nothing. With ``consensus(frag_i,
        frag_j, desc_i, desc_j) -> int`` (how many matches one rigid transform explains:
        RANSAC's inliers) scan j is described in each of :meth:`candidates`, ``screen`` (a
        cheaper consensus, by default ``consensus`` itself) ranks them, and the best is kept
        unless ``consensus`` finds more agreement in the first pass — a choice made from the
        scans alone. Without a consensus the strongest mode is kept."""
        screen = screen or consensus
        cache, inputs, votes = {}, {}, {}
        for i, j in progress_bar(list(pairs)):
            for k in (i, j):
                if k not in cache:
                    cache[k] = self.first(frags[k])
            (d_i, f_i, s_i), (d_j, f_j, s_j) = cache[i], cache[j]
            ia, ib = match(d_i, d_j)
            again_i = self.again(frags[i], s_i, np.eye(3))
            if consensus is None:
                vote = vote_rotation(f_i[ia], f_j[ib], self.tol_deg)
                votes[(i, j)] = vote
                inputs[(i, j)] = (again_i, self.again(frags[j], s_j, vote.rotation.T))
                continue
            best = None
            for rank, vote in enumerate(self.candidates(f_i[ia], f_j[ib], frags[i].normals)):
                second = (again_i, self.again(frags[j], s_j, vote.rotation.T))
                agreed = screen(frags[i], frags[j], *second)
                if best is None or agreed > best[2]:
                    best = (vote._replace(mode=0 if vote.box_turn_deg else rank), second,
                            agreed)
            vote, second, _ = best
            if consensus(frags[i], frags[j], d_i, d_j) > consensus(frags[i], frags[j], *second):
                vote, second = vote._replace(second_pass=False), (d_i, d_j)
            votes[(i, j)], inputs[(i, j)] = vote, second
        return inputs, votes
