"""The registration pipeline on two scans: voxel grid → keypoints → descriptors → mutual
matches → RANSAC (and its best rival) → point-to-plane ICP, with every setting in one
:class:`Settings` (as open3d groups estimation, checkers and criteria).

Descriptors come in as a function (:mod:`sphere_jax.features` makes them by name), so this
layer needs no trained network. :func:`register` describes a random quarter of the keypoints
first, then half, then all (:data:`PROGRESSIVE_SHARES`), and stops at the first share whose
result is confident; each share describes only the keypoints new to it.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np

from sphere_jax.registration.estimation import (point_to_plane_icp, ransac_consensus,
                                                rival_consensus)
from sphere_jax.registration.fragments import Fragment, fragment
from sphere_jax.registration.matching import mutual_matches

# Per cloud: the fewest that keep LEAD-PN's registration recall on the 27 redkitchen pairs
# (5000: 23/27, 2500: 19/27, 1000: 19/27; the low-overlap pairs gain, docs/performance.md).
DEFAULT_KEYPOINTS = 5000
# A result is registered (confident) with CONFIDENT_INLIERS RANSAC inliers and RIVAL_MARGIN
# times those of the best other transform among the matches it leaves unexplained
# (estimation.rival_consensus): inliers alone are evidence, not proof (LEAD-PN registered a
# LiDAR rescan pair 92 degrees off with 41). Both were chosen by
# python -m experiments.registered --fit on validation pairs of no evaluation scene (stairs,
# shelf-bin, held-out synthetic rooms; docs/usage.md): the fewest that call no wrong result
# there registered, keeping the most right ones.
PROGRESSIVE_SHARES = (0.25, 0.5, 1.0)
CONFIDENT_INLIERS = 50
RIVAL_MARGIN = 2.25

# Below these a registration is reported as failed, not as a result.
MIN_POINTS = 10          # voxelised points per cloud
MIN_MATCHES = 3          # mutual matches: RANSAC's minimal sample
MIN_INLIERS = 10         # RANSAC's consensus
MIN_FITNESS = 0.05       # ICP: share of source points with a target point within reach
REACH = 2.5              # RANSAC's and ICP's distance, in voxels


@dataclasses.dataclass(frozen=True)
class Settings:
    """Everything a registration is decided by, checked once where it is made
    (:func:`sphere_jax.align.register`). ``voxel`` and ``radius`` in the clouds' unit; NaN
    when too few points gave no scale (the result then says so)."""
    voxel: float
    radius: float
    n_keypoints: int = DEFAULT_KEYPOINTS
    seed: int = 0
    icp: bool = True
    min_inliers: int = MIN_INLIERS
    min_fitness: float = MIN_FITNESS
    progressive: bool = True

    @property
    def distance(self) -> float:
        """RANSAC's and ICP's correspondence distance."""
        return REACH * self.voxel


@dataclasses.dataclass
class Registration:
    """``transform`` maps the source onto the target: ``p_target = T · p_source``. A
    registration that did not succeed says so: ``ok`` is False and ``reason`` says why (too few
    points, no mutual matches, no RANSAC consensus, ICP fitness below the threshold); its
    ``transform`` is then the best guess, not a result. One that succeeded with fewer than
    :data:`CONFIDENT_INLIERS` RANSAC inliers, or fewer than :data:`RIVAL_MARGIN` times its
    ``rival``'s, is not ``confident``: its summary calls it unconfirmed."""
    transform: np.ndarray
    inliers: int            # matches within the RANSAC distance under the RANSAC transform
    matches: int            # mutual nearest neighbours in descriptor space
    fitness: float          # ICP: share of source points with a target point within reach
    rmse: float             # ICP: RMS distance of those pairs (the clouds' unit)
    voxel: float
    radius: float
    method: str
    seconds: dict           # per stage
    reason: str = ""        # why it failed; '' when it succeeded
    adaptation: str = ""    # what adapting did (register(adapt=...)), per network
    kept: str = ""          # with adapt: whether this is the adapted or the given bundles' result
    keypoints: tuple = ()   # (described, drawn) per cloud, source first
    rival: int = -1         # RANSAC inliers of the best other transform; -1: not measured

    @property
    def ok(self) -> bool:
        return not self.reason

    @property
    def confident(self) -> bool:
        """Succeeded with at least :data:`CONFIDENT_INLIERS` RANSAC inliers and
        :data:`RIVAL_MARGIN` times as many as the best other transform: the status
        ``registered``; from a share of the keypoints (:data:`PROGRESSIVE_SHARES`), good enough
        not to describe more."""
        return self.ok and not self.doubt()

    def doubt(self) -> str:
        """Why a result that succeeded is unconfirmed ('' when it is not)."""
        if self.inliers < CONFIDENT_INLIERS:
            return (f"{self.inliers} RANSAC inliers, fewer than the {CONFIDENT_INLIERS} below "
                    f"which registrations of the validation pairs were sometimes wrong")
        if self.inliers < RIVAL_MARGIN * self.rival:
            return (f"{self.inliers} RANSAC inliers against {self.rival} for another "
                    f"transform, less than {RIVAL_MARGIN:g} times as many")
        return ""

    def summary(self) -> str:
        t = "\n".join("  " + " ".join(f"{v: .6f}" for v in row) for row in self.transform)
        times = ", ".join(f"{k} {v:.2f} s" for k, v in self.seconds.items())
        if not self.ok:
            status = f"FAILED: {self.reason}"
        elif self.confident:
            status = "registered"
        else:
            status = f"registered, unconfirmed: {self.doubt()}; check the result before using it"
        icp = (f"ICP fitness {self.fitness:.3f}, RMSE {self.rmse:.4g}"
               if np.isfinite(self.fitness) else "no ICP")
        rival = f" (another transform: {self.rival})" if self.rival >= 0 else ""
        return (f"{status}\np_target = T · p_source with T =\n{t}\n{self.method}: "
                f"{self.matches} mutual matches, {self.inliers} RANSAC inliers{rival}; {icp}\n"
                + (f"voxel {self.voxel:.4g}, radius {self.radius:.4g}"
                   if np.isfinite(self.voxel) else "no voxel or radius chosen")
                + f"{self._described()}\n"
                f"{times}"
                + (f"\nadapted {self.adaptation}" if self.adaptation else "")
                + (f"\nkept {self.kept}" if self.kept else ""))

    def _described(self) -> str:
        if not self.keypoints:
            return ""
        return "; keypoints described " + ", ".join(f"{d} of {n}" for d, n in self.keypoints)


class Stopwatch:
    """Seconds per stage; a stage run more than once (share by share) adds up."""

    def __init__(self):
        self.seconds, self._t0 = {}, time.perf_counter()

    def lap(self, stage):
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self._t0
        self._t0 = now

    def muted(self) -> Stopwatch:
        """A stopwatch that records nothing into the same stages (a run timed as a whole)."""
        quiet = Stopwatch()
        quiet.seconds, quiet.lap = self.seconds, lambda stage: None
        return quiet


def failed(settings: Settings, method, watch: Stopwatch, reason, matches=0) -> Registration:
    return Registration(np.eye(4), 0, matches, np.nan, np.nan, settings.voxel, settings.radius,
                        method, watch.seconds, reason)


def prepare(source_Nx3, target_Mx3, settings: Settings, method, watch: Stopwatch):
    """``(source, target)`` fragments on the voxel grid with their keypoints, or the failed
    :class:`Registration` that says which cloud has too few points."""
    few = [(name, len(p)) for name, p in (("source", source_Nx3), ("target", target_Mx3))
           if len(p) < MIN_POINTS]
    if few:
        return failed(settings, method, watch, "too few points: " + ", ".join(
            f"{n} has {k}" for n, k in few) + f" (at least {MIN_POINTS})")
    seed, voxel = settings.seed, settings.voxel
    src = fragment("source", source_Nx3, voxel, np.random.default_rng(seed),
                   settings.n_keypoints)
    dst = fragment("target", target_Mx3, voxel, np.random.default_rng(seed + 1),
                   settings.n_keypoints)
    watch.lap("voxels, normals, keypoints")
    few = [(name, len(f.points)) for name, f in (("source", src), ("target", dst))
           if len(f.points) < MIN_POINTS]
    if few:
        return failed(settings, method, watch, "too few points on the voxel grid: " + ", ".join(
            f"{n} has {k} at voxel {voxel:.4g}" for n, k in few) + f" (at least {MIN_POINTS})")
    return src, dst


def share_counts(n: int, progressive: bool = True) -> list[int]:
    """How many of ``n`` drawn keypoints are described once each share is
    (:data:`PROGRESSIVE_SHARES`; all at once when not ``progressive``)."""
    return [int(np.ceil(share * n)) for share in (PROGRESSIVE_SHARES if progressive else (1.0,))]


def _take(f, idx):
    """Fragment ``f`` with its keypoints ``f.keypoints[idx]``."""
    return dataclasses.replace(f, keypoints=f.keypoints[idx])


def register(src: Fragment, dst: Fragment, describe: Callable, settings: Settings, method,
             watch: Stopwatch) -> Registration:
    """Describe (``describe([fragments]) -> [descriptors [K, D]]``, one stream for both), match,
    RANSAC and ICP two prepared fragments, share by share of the keypoints when
    ``settings.progressive``."""
    drawn = (len(src.keypoints), len(dst.keypoints))
    # The keypoints come sorted by index, i.e. by place: a permutation's first share of them
    # is a random share.
    orders = [np.random.default_rng(settings.seed).permutation(n) for n in drawn]
    described = [None, None]
    for upto in zip(*(share_counts(n, settings.progressive) for n in drawn)):
        done = [0 if d is None else len(d) for d in described]
        # one stream for both scans: no core idles between them
        new = describe([_take(f, o[a:b]) for f, o, a, b in zip((src, dst), orders, done, upto)])
        described = [n if d is None else np.concatenate([d, n]) for d, n in zip(described, new)]
        watch.lap("descriptors")
        if upto == drawn:                # all of them, in their own order again
            result = estimate(src, dst, *(d[np.argsort(o)] for d, o in zip(described, orders)),
                              settings, method, watch)
        else:
            result = estimate(*(_take(f, o[:b]) for f, o, b in zip((src, dst), orders, upto)),
                              *described, settings, method, watch)
        result = dataclasses.replace(result, keypoints=tuple(zip(upto, drawn)))
        if upto == drawn or result.confident:
            return result


def register_described(src: Fragment, dst: Fragment, d_src, d_dst, settings: Settings, method,
                       watch: Stopwatch) -> Registration:
    """:func:`estimate` on descriptors of every keypoint made at once (the pair vote's)."""
    drawn = (len(src.keypoints), len(dst.keypoints))
    return dataclasses.replace(estimate(src, dst, d_src, d_dst, settings, method, watch),
                               keypoints=tuple(zip(drawn, drawn)))


def estimate(src, dst, d_src, d_dst, settings: Settings, method,
             watch: Stopwatch) -> Registration:
    """Mutual matches of the described keypoints, RANSAC, its rival and ICP."""
    distance, seed = settings.distance, settings.seed
    voxel, radius = settings.voxel, settings.radius
    ia, ib = mutual_matches(d_src, d_dst)
    watch.lap("matching")
    if len(ia) < MIN_MATCHES:
        return failed(settings, method, watch, f"{len(ia)} mutual matches (RANSAC needs "
                                               f"{MIN_MATCHES})", matches=len(ia))
    p_dst, p_src = dst.points[dst.keypoints[ib]], src.points[src.keypoints[ia]]
    t, inliers = ransac_consensus(p_dst, p_src, distance, seed=seed)
    watch.lap("RANSAC")
    if inliers < settings.min_inliers:
        return Registration(t, inliers, len(ia), np.nan, np.nan, voxel, radius, method,
                            watch.seconds,
                            f"RANSAC found no consensus: {inliers} inliers of {len(ia)} "
                            f"matches (min_inliers={settings.min_inliers})")
    rival = rival_consensus(p_dst, p_src, t, distance, same_distance=radius, seed=seed + 1)
    watch.lap("RANSAC")
    fitness, rmse, reason = np.nan, np.nan, ""
    if settings.icp:
        t, fitness, rmse = point_to_plane_icp(src, dst, t, distance)
        watch.lap("ICP")
        if fitness < settings.min_fitness:
            reason = (f"ICP fitness {fitness:.3f} is below min_fitness={settings.min_fitness}: "
                      f"the clouds do not overlap under the found transform")
    return Registration(t, inliers, len(ia), fitness, rmse, voxel, radius, method,
                        watch.seconds, reason, rival=rival)
