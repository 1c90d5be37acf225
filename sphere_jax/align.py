"""Register two scans in one call: voxel grid → keypoints → descriptors → mutual matches →
RANSAC → point-to-plane ICP (``sphere_jax.register``; the command line is
``python -m experiments.register SOURCE TARGET``).

The scale is chosen from the clouds when not given: the shipped networks were trained on room
fragments at 3DMatch's scale, voxelised at 2 cm with 0.3 m supports — 15 voxels, about 700
points on a surface — and a 3DMatch fragment's middle bounding-box side (2–98 % of its
points) is about 2.1 m.
``voxel = auto`` keeps that proportion (side × 0.02 / 2.1) unless the scan is sparser than that
(then its own point spacing), and ``radius = auto`` is 15 voxels, so a support holds as many
points as at training time whatever the unit: a Stanford scan (middle side 0.12 m) gets
1.2 mm voxels and 1.8 cm supports, close to the seed's 1.5 cm.
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import tempfile
import time

import numpy as np
from scipy.spatial import cKDTree

from sphere_jax import checks, paths
from sphere_jax.features import registry
from sphere_jax.registration.estimation import (SCREEN_ITERATIONS, consensus,
                                                point_to_plane_icp, ransac_consensus,
                                                rival_consensus)
from sphere_jax.registration.fragments import fragment
from sphere_jax.registration.matching import mutual_matches

TRAIN_VOXEL, TRAIN_RADIUS = 0.02, 0.30      # the shipped bundles' data.voxel and data.radius
FRAGMENT_SIDE = 2.1                         # middle bounding-box side of a 3DMatch fragment, m
DEFAULT_METHOD = "lead_pn"                  # the best shipped learned descriptor (README)
# Per cloud: the fewest that keep LEAD-PN's registration recall on the 27 redkitchen pairs
# (5000: 23/27, 2500: 19/27, 1000: 19/27; the low-overlap pairs gain, docs/performance.md).
DEFAULT_KEYPOINTS = 5000
# register describes a random quarter of them first, then half, then all, and stops at the
# first share whose registration has at least CONFIDENT_INLIERS RANSAC inliers and ICP's
# agreement; only the newly drawn keypoints are described at each share. On the 27 redkitchen
# pairs and LiDAR rescans of them, with every learned and hand-crafted method, no registration
# from a quarter or half of the keypoints with that many inliers was wrong (wrong ones had at
# most 18; docs/performance.md, docs/usage.md).
PROGRESSIVE_SHARES = (0.25, 0.5, 1.0)
CONFIDENT_INLIERS = 40
# ... and RIVAL_MARGIN times the consensus of the best other transform among the matches it
# leaves unexplained (registration.estimation.rival_consensus): inliers alone are evidence, not
# proof (LEAD-PN registered a LiDAR rescan pair 92 degrees off with 41, register put the bunny's
# top3 onto bun180 flipped with 70). Chosen on validation pairs of no evaluation scene by
# python -m experiments.registered --fit (docs/usage.md).
RIVAL_MARGIN = 2.0
# Fewer inliers than that and the result says it is unconfirmed even from all keypoints:
# wrong registrations that passed MIN_INLIERS and MIN_FITNESS there had up to 29 (LEAD-PN,
# FPFH, SHOT and USC on the 27 pairs; docs/usage.md). Where scans overlap little inliers prove
# less: the 10000-step LEAD-PN registers the LiDAR rescans of redkitchen 59 -> 21 (3DLoMatch)
# 92 degrees off with 41, and two of the bunny's view pairs are wrong with 62 and 120.
# The methods register takes, by key (:mod:`sphere_jax.features.registry`; grammar names such
# as ``lead@compass`` resolve to them).
LEARNED = tuple(m.key for m in registry.METHODS if m.kind == "descriptor" and m.learned)
HANDCRAFTED = tuple(m.key for m in registry.METHODS if m.kind == "descriptor" and not m.learned)
VOTED = registry.keys("voted")             # described again in a frame voted by a first pass


# Below these a registration is reported as failed, not as a result.
MIN_POINTS = 10          # voxelised points per cloud
MIN_MATCHES = 3          # mutual matches: RANSAC's minimal sample
MIN_INLIERS = 10         # RANSAC's consensus
MIN_FITNESS = 0.05       # ICP: share of source points with a target point within reach
REACH = 2.5              # RANSAC's and ICP's distance, in voxels


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
    rival: int = -1         # RANSAC inliers of the best other transform; -1: not measured
    adaptation: str = ""    # what adapting did (register(adapt=...)), per network
    kept: str = ""          # with adapt: whether this is the adapted or the given bundles' result
    keypoints: tuple = ()   # (described, drawn) per cloud, source first

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
                    f"which registrations of the redkitchen pairs were sometimes wrong")
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


def middle_side(points_Nx3) -> float:
    """The middle side of the box holding 2–98 % of the points on each axis (robust to
    stray points; a room fragment's is its width, a flat scan's its shorter horizontal side)."""
    lo, hi = np.percentile(points_Nx3, 2, axis=0), np.percentile(points_Nx3, 98, axis=0)
    return float(np.sort(hi - lo)[1])


def point_spacing(points_Nx3, samples=5000, seed=0) -> float:
    """Median distance from a point to its nearest other point (sampled queries, full tree)."""
    rng = np.random.default_rng(seed)
    query = points_Nx3[rng.choice(len(points_Nx3), min(samples, len(points_Nx3)), False)]
    d = cKDTree(points_Nx3).query(query, k=2)[0][:, 1]
    d = d[d > 0]
    return float(np.median(d)) if len(d) else 0.0


def auto_scale(*clouds):
    """``(voxel, radius)`` for the clouds (``[N, 3]`` each) of one scene or sensor (module
    docstring): the largest middle side decides, unless a cloud is sparser than that."""
    side = max(middle_side(c) for c in clouds)
    voxel = max([side * TRAIN_VOXEL / FRAGMENT_SIDE] + [point_spacing(c) for c in clouds])
    if not voxel > 0:
        raise checks.InputError("the clouds", "clouds with extent",
                                "clouds whose points coincide")
    return voxel, voxel * TRAIN_RADIUS / TRAIN_VOXEL


def register(source, target, method=DEFAULT_METHOD, voxel="auto", radius="auto",
             n_keypoints=DEFAULT_KEYPOINTS, seed=0, bundle=None, icp=True,
             min_inliers=MIN_INLIERS, min_fitness=MIN_FITNESS, adapt=None,
             adapt_workdir=None, progressive=True) -> Registration:
    """Register ``source`` onto ``target`` (``[N, 3]`` arrays, open3d point clouds or file
    paths, any unit).

    Args:
      method: by its name or key (:mod:`sphere_jax.features.registry`): a learned descriptor
        (``lead_pn``, the default; ``lead@flare``, ``lead@compass``, ``sound``: the shipped
        bundles), a hand-crafted one (``fpfh``, ``shot``, ``spin``, ``usc``), or one with the
        pair vote (``lead@compass+vote``, ``shot+vote``: :mod:`sphere_jax.registration.vote`;
        on the redkitchen pairs they nearly double the inlier ratio; the LEAD one costs what
        ``lead@compass`` does, plus the matching). ``Registration.method`` is the key.
      voxel, radius: grid size and support radius in the clouds' unit, or ``"auto"``
        (:func:`auto_scale`).
      n_keypoints: random keypoints per cloud on the voxel grid.
      progressive: describe a quarter of them first, then half, then all
        (:data:`PROGRESSIVE_SHARES`), and stop at the first share that registers with at least
        ``CONFIDENT_INLIERS`` RANSAC inliers (and ICP's agreement); each share describes only
        the keypoints new to it (``Registration.keypoints`` says how many were described).
        The pair vote describes all at once.
      bundle: a bundle (folder or kind) replacing the shipped one of its kind, or several (a
        list, or comma-separated).
      icp: refine the RANSAC transform by point-to-plane ICP.
      min_inliers, min_fitness: below these RANSAC inliers or ICP fitness the result is a
        failure (``ok`` False, with the reason), as it is with fewer than ``MIN_POINTS``
        voxelised points in a cloud or ``MIN_MATCHES`` mutual matches.
      adapt: minutes (wall time) of adaptation of the method's networks to these two scans,
        without labels (:func:`adapted_bundles`: Compass and LEAD side by side for
        ``lead@compass``; a method without a network is refused). The scans are registered
        with the bundles as given and with the adapted ones, and the better result returned
        (a success over a failure, then more RANSAC inliers; ``Registration.kept`` says
        which). ``adapt_workdir`` keeps the adapted bundles
        (``<adapt_workdir>/<kind>/bundle``, reusable with ``bundle=``), else a temporary
        folder does.
    """
    chosen = registry.resolve(method, ("descriptor", "voted"))
    method = chosen.key
    source, target = (_points(x, name) for x, name in ((source, "source"), (target, "target")))
    few = [(name, len(p)) for name, p in (("source", source), ("target", target))
           if len(p) < MIN_POINTS]
    # Too few points to measure a scale by: the result below says so, with no scale chosen.
    auto_voxel, auto_radius = (auto_scale(source, target) if "auto" in (voxel, radius)
                               and not few else (np.nan, np.nan))
    voxel = auto_voxel if voxel == "auto" else checks.positive(voxel, "voxel")
    radius = auto_radius if radius == "auto" else checks.positive(radius, "radius")
    n_keypoints = checks.positive(n_keypoints, "n_keypoints", integer=True)
    seed = checks.non_negative(seed, "seed", integer=True)
    bundles = method_bundles(chosen, bundle)
    adapt = None if adapt is None else checks.positive(adapt, "adapt")
    if adapt and not adapted_kinds(chosen):
        able = [m.name for m in registry.METHODS if m.kind != "diagnostic" and adapted_kinds(m)]
        raise checks.InputError("adapt", f"used with a learned method ({', '.join(able)})",
                                f"method {chosen.name!r}, which has no network to adapt")
    seconds, t0 = {}, time.perf_counter()

    def lap(stage):                     # a stage run twice (progressive) adds up
        nonlocal t0
        seconds[stage] = seconds.get(stage, 0.0) + time.perf_counter() - t0
        t0 = time.perf_counter()

    min_inliers = checks.non_negative(min_inliers, "min_inliers", integer=True)
    min_fitness = checks.fraction(min_fitness, "min_fitness")
    icp = checks.flag(icp, "icp")
    progressive = checks.flag(progressive, "progressive")

    def fail(reason, matches=0):
        return Registration(np.eye(4), 0, matches, np.nan, np.nan, voxel, radius, method,
                            seconds, reason)

    if few:
        return fail(reason="too few points: " + ", ".join(f"{n} has {k}" for n, k in few)
                    + f" (at least {MIN_POINTS})")
    src = fragment("source", source, voxel, np.random.default_rng(seed), n_keypoints)
    dst = fragment("target", target, voxel, np.random.default_rng(seed + 1), n_keypoints)
    lap("voxels, normals, keypoints")
    few = [(name, len(f.points)) for name, f in (("source", src), ("target", dst))
           if len(f.points) < MIN_POINTS]
    if few:
        return fail(reason="too few points on the voxel grid: " + ", ".join(
            f"{n} has {k} at voxel {voxel:.4g}" for n, k in few) + f" (at least {MIN_POINTS})")
    match = functools.partial(_match, src, dst, method, voxel=voxel, radius=radius, seed=seed,
                              icp=icp, min_inliers=min_inliers, min_fitness=min_fitness,
                              seconds=seconds, fail=fail, progressive=progressive)
    if not adapt:
        return match(bundles=bundles, lap=lap)
    # Adapting on two scans can lose a pair the bundles as given register (LiDAR rescans of
    # redkitchen 34 -> 6: 15 RANSAC inliers and 2 degrees off before, FAILED after), so both
    # registrations are made and the better kept: adapting never turns a success into a failure.
    given = match(bundles=bundles, lap=lambda stage: None)
    lap("registration with the bundles as given")
    with contextlib.ExitStack() as stack:        # a temporary folder lives while it is used
        folder = adapt_workdir or stack.enter_context(tempfile.TemporaryDirectory())
        adapted, note = adapted_bundles(method, bundles, source, target, voxel, radius, adapt,
                                        folder)
        lap("adaptation")
        after = match(bundles=adapted, lap=lap)
    best, kept = _better(after, given)
    return dataclasses.replace(best, adaptation=note, kept=kept)


def _better(adapted: Registration, given: Registration):
    """The registration to keep of the adapted bundles' and the given ones' — a success over a
    failure, then more RANSAC inliers (ties: the adapted one) — and which it is, in words."""
    rank = lambda r: (r.ok, r.inliers)
    say = lambda r: f"{'' if r.ok else 'FAILED, '}{r.inliers} RANSAC inliers"
    if rank(adapted) >= rank(given):
        return adapted, (f"the adapted bundles' result ({say(adapted)}; with the bundles "
                         f"as given: {say(given)})")
    return given, f"the result of the bundles as given ({say(given)}; adapted: {say(adapted)})"


def method_bundles(method: registry.Method, bundle=None):
    """Kind -> bundle path for the shipped bundles, ``bundle`` (a folder or kind, or several:
    a list or a comma-separated string) replacing the one of its kind;
    :class:`~sphere_jax.checks.InputError` when ``method`` needs no bundle of that kind or two
    are of one kind, so that a bundle given is never silently left unused."""
    bundles = {k: paths.shipped_bundle(k) for k in ("lead", "compass", "lead_pn", "sound")}
    given = split_bundles(bundle)
    if given:
        from sphere_jax.bundles import inference, store
        # The kind is the config's: the weights are read once, where they are used.
        kinds = one_per_kind([store.read_config(inference.bundle_path(b)).model
                              for b in given])
        for b, kind in zip(given, kinds):
            if kind not in method.needs:
                raise checks.InputError("bundle", f"of a kind that method {method.key!r} uses "
                                        f"({', '.join(method.needs) or 'none: no network'})",
                                        f"a {kind} bundle")
            bundles[kind] = inference.bundle_path(b)
    return bundles


def split_bundles(bundle) -> list:
    """``bundle`` as a list: None -> [], a comma-separated string -> its entries."""
    if bundle is None:
        return []
    if isinstance(bundle, str):
        return [b.strip() for b in bundle.split(",") if b.strip()]
    return list(bundle)


def one_per_kind(kinds: list) -> list:
    """``kinds`` (of the bundles given as ``bundle``), or
    :class:`~sphere_jax.checks.InputError` when two are of one kind: which one would be used
    is not the user's to guess."""
    for kind in kinds:
        if kinds.count(kind) > 1:
            raise checks.InputError("bundle", "one bundle per kind",
                                    f"{kinds.count(kind)} {kind} bundles")
    return kinds


def adapted_kinds(method: registry.Method) -> tuple[str, ...]:
    """The bundle kinds ``adapt`` fine-tunes for ``method``: every network it uses, all of
    them trained without labels (Compass and LEAD for ``lead@compass``)."""
    from sphere_jax.training import adaptation
    return tuple(k for k in method.needs if k in adaptation.adaptable_kinds())


def adapted_bundles(method, bundles, source, target, voxel, radius, minutes, workdir,
                    progress=True):
    """``bundles`` with the networks ``method`` uses (:func:`adapted_kinds`) adapted to the
    two scans for ``minutes`` of wall time, each with its own loss and no label
    (:mod:`sphere_jax.training`), at the registration's voxel and radius; two networks adapt
    side by side, one process each on its share of the cores
    (:mod:`~sphere_jax.training.side_by_side`). Descriptors keep their bundle's whitening
    (:func:`~sphere_jax.features.whitening_fit.keep_from`: two scans are too few to fit one).
    Returns ``(bundles, what each adaptation did)``.

    Why both networks of ``lead@compass``: on the bunny's ten scans, 10 minutes of Compass and
    LEAD side by side raised LEAD (Compass)'s inlier ratio by 26 %, Compass's frames alone for
    as long by 12 %. Two scans teach less: 5 minutes on each of four bunny pairs the shipped
    bundles fail registered none of them, nor a LiDAR pair, and another they lost
    (docs/training.md; :func:`register` keeps the better result)."""
    from sphere_jax.bundles import inference, store
    from sphere_jax.features import whitening_fit
    from sphere_jax.training import adaptation, side_by_side
    kinds = adapted_kinds(registry.resolve(method))
    os.makedirs(workdir, exist_ok=True)
    scans = []
    for name, points in (("source", source), ("target", target)):
        scans.append(os.path.join(workdir, f"{name}.npy"))
        np.save(scans[-1], np.asarray(points, np.float32))
    scans = ",".join(scans)
    folders = {k: inference.bundle_path(bundles[k]) for k in kinds}
    jobs = [(k, folders[k], os.path.join(workdir, k),
             adaptation.data_at_scale(store.read_config(folders[k]), voxel, radius))
            for k in kinds]
    adapted = side_by_side.adapt_side_by_side(jobs, scans, minutes=minutes, progress=progress)
    out = dict(bundles)
    for kind, path in zip(kinds, adapted):
        whitening_fit.keep_from(bundles[kind], path)
        out[kind] = path
    return out, "; ".join(adaptation.outcome(out[k]) for k in kinds)


def share_counts(n: int, progressive: bool = True) -> list[int]:
    """How many of ``n`` drawn keypoints are described once each share is
    (:data:`PROGRESSIVE_SHARES`; all at once when not ``progressive``)."""
    return [int(np.ceil(share * n)) for share in (PROGRESSIVE_SHARES if progressive else (1.0,))]


def _take(f, idx):
    """Fragment ``f`` with its keypoints ``f.keypoints[idx]``."""
    return dataclasses.replace(f, keypoints=f.keypoints[idx])


def _match(src, dst, method, bundles, voxel, radius, seed, icp, min_inliers, min_fitness,
           seconds, lap, fail, progressive):
    """Describe, match, RANSAC and ICP two prepared fragments (:func:`register`), share by
    share of the keypoints (:data:`PROGRESSIVE_SHARES`) when ``progressive``."""
    from sphere_jax.features import methods, voted
    estimate = functools.partial(_estimate, voxel=voxel, radius=radius, method=method,
                                 seed=seed, icp=icp, min_inliers=min_inliers,
                                 min_fitness=min_fitness, seconds=seconds, lap=lap, fail=fail)
    drawn = (len(src.keypoints), len(dst.keypoints))
    if method in VOTED:
        frames = voted.voted_frames(method, radius, bundles)
        agree = functools.partial(consensus, max_distance=REACH * voxel, seed=seed)
        screen = functools.partial(agree, iterations=SCREEN_ITERATIONS)
        inputs, _ = frames.describe_pairs({"target": dst, "source": src},
                                          [("target", "source")], mutual_matches, agree,
                                          screen=screen)
        d_dst, d_src = inputs[("target", "source")]     # p_target = T p_source: (i, j)
        lap("descriptors")
        return dataclasses.replace(estimate(src, dst, d_src, d_dst),
                                   keypoints=tuple(zip(drawn, drawn)))
    describe = methods.descriptor_of_many(method, radius, bundles)
    # The keypoints come sorted by index, i.e. by place: a permutation's first share of them
    # is a random share.
    orders = [np.random.default_rng(seed).permutation(n) for n in drawn]
    described = [None, None]
    for upto in zip(*(share_counts(n, progressive) for n in drawn)):
        done = [0 if d is None else len(d) for d in described]
        # one stream for both scans: no core idles between them
        new = describe([_take(f, o[a:b]) for f, o, a, b in zip((src, dst), orders, done, upto)])
        described = [n if d is None else np.concatenate([d, n]) for d, n in zip(described, new)]
        lap("descriptors")
        if upto == drawn:                # all of them, in their own order again
            result = estimate(src, dst, *(d[np.argsort(o)] for d, o in zip(described, orders)))
        else:
            result = estimate(*(_take(f, o[:b]) for f, o, b in zip((src, dst), orders, upto)),
                              *described)
        result = dataclasses.replace(result, keypoints=tuple(zip(upto, drawn)))
        if upto == drawn or result.confident:
            return result


def _estimate(src, dst, d_src, d_dst, voxel, radius, method, seed, icp, min_inliers,
              min_fitness, seconds, lap, fail):
    """Mutual matches of the described keypoints, RANSAC and ICP: a :class:`Registration`."""
    distance = REACH * voxel
    ia, ib = mutual_matches(d_src, d_dst)
    lap("matching")
    if len(ia) < MIN_MATCHES:
        return fail(matches=len(ia), reason=f"{len(ia)} mutual matches (RANSAC needs "
                                            f"{MIN_MATCHES})")
    p_dst, p_src = dst.points[dst.keypoints[ib]], src.points[src.keypoints[ia]]
    t, inliers = ransac_consensus(p_dst, p_src, distance, seed=seed)
    lap("RANSAC")
    if inliers < min_inliers:
        return Registration(t, inliers, len(ia), np.nan, np.nan, voxel, radius, method, seconds,
                            f"RANSAC found no consensus: {inliers} inliers of {len(ia)} "
                            f"matches (min_inliers={min_inliers})")
    rival = rival_consensus(p_dst, p_src, t, distance, same_distance=radius, seed=seed + 1)
    lap("RANSAC")
    fitness, rmse, reason = np.nan, np.nan, ""
    if icp:
        t, fitness, rmse = point_to_plane_icp(src, dst, t, distance)
        lap("ICP")
        if fitness < min_fitness:
            reason = (f"ICP fitness {fitness:.3f} is below min_fitness={min_fitness}: the "
                      f"clouds do not overlap under the found transform")
    return Registration(t, inliers, len(ia), fitness, rmse, voxel, radius, method, seconds,
                        reason, rival=rival)


def _points(x, name):
    if isinstance(x, (str, bytes)) or hasattr(x, "__fspath__"):
        from sphere_jax.data.readers import io
        return io.read_points(x).points
    return checks.cloud(x, name)
