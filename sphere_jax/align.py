"""Register two scans in one call (``sphere_jax.register``; the command line is
``python -m experiments.register SOURCE TARGET``): the boundary where the inputs are checked
once and the method, its bundles and the scale are chosen, and where adapting the networks to
the two scans is weighed against the bundles as given. The pipeline itself is
:mod:`sphere_jax.registration.pipeline`; the scale, :mod:`sphere_jax.registration.scale`.
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import tempfile

import numpy as np

from sphere_jax import checks
from sphere_jax.features import registry
from sphere_jax.models import shipped
from sphere_jax.registration import pipeline
from sphere_jax.registration.estimation import SCREEN_ITERATIONS, consensus
from sphere_jax.registration.matching import mutual_matches
from sphere_jax.registration.pipeline import DEFAULT_KEYPOINTS, MIN_FITNESS, MIN_INLIERS
from sphere_jax.registration.scale import auto_scale

DEFAULT_METHOD = "lead_pn"                  # the best shipped learned descriptor (README)


def register(source, target, method=DEFAULT_METHOD, voxel="auto", radius="auto",
             n_keypoints=DEFAULT_KEYPOINTS, seed=0, bundle=None, icp=True,
             min_inliers=MIN_INLIERS, min_fitness=MIN_FITNESS, adapt=None,
             adapt_workdir=None, progressive=True) -> pipeline.Registration:
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
        (:func:`~sphere_jax.registration.scale.auto_scale`).
      n_keypoints: random keypoints per cloud on the voxel grid.
      progressive: describe a quarter of them first, then half, then all
        (:data:`~sphere_jax.registration.pipeline.PROGRESSIVE_SHARES`), and stop at the first
        share whose result is confident (``Registration.confident``); each share describes only
        the keypoints new to it (``Registration.keypoints`` says how many were described).
        The pair vote describes all at once.
      bundle: a bundle (folder or kind) replacing the shipped one of its kind, or several (a
        list, or comma-separated).
      icp: refine the RANSAC transform by point-to-plane ICP.
      min_inliers, min_fitness: below these RANSAC inliers or ICP fitness the result is a
        failure (``ok`` False, with the reason), as it is with fewer than
        :data:`~sphere_jax.registration.pipeline.MIN_POINTS` voxelised points in a cloud or
        ``MIN_MATCHES`` mutual matches. Every argument is checked here, once, and the
        pipeline runs on one :class:`~sphere_jax.registration.pipeline.Settings`.
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
    few = min(len(source), len(target)) < pipeline.MIN_POINTS
    # Too few points to measure a scale by: the result says so, with no scale chosen.
    auto_voxel, auto_radius = (auto_scale(source, target) if "auto" in (voxel, radius)
                               and not few else (np.nan, np.nan))
    settings = pipeline.Settings(
        voxel=auto_voxel if voxel == "auto" else checks.positive(voxel, "voxel"),
        radius=auto_radius if radius == "auto" else checks.positive(radius, "radius"),
        n_keypoints=checks.positive(n_keypoints, "n_keypoints", integer=True),
        seed=checks.non_negative(seed, "seed", integer=True),
        icp=checks.flag(icp, "icp"),
        min_inliers=checks.non_negative(min_inliers, "min_inliers", integer=True),
        min_fitness=checks.fraction(min_fitness, "min_fitness"),
        progressive=checks.flag(progressive, "progressive"))
    bundles = method_bundles(chosen, bundle)
    adapt = None if adapt is None else checks.positive(adapt, "adapt")
    if adapt and not adapted_kinds(chosen):
        able = [m.name for m in registry.METHODS if m.kind != "diagnostic" and adapted_kinds(m)]
        raise checks.InputError("adapt", f"used with a learned method ({', '.join(able)})",
                                f"method {chosen.name!r}, which has no network to adapt")
    watch = pipeline.Stopwatch()
    prepared = pipeline.prepare(source, target, settings, method, watch)
    if isinstance(prepared, pipeline.Registration):
        return prepared
    src, dst = prepared
    if not adapt:
        return _match(src, dst, method, bundles, settings, watch)
    # Adapting on two scans can lose a pair the bundles as given register (LiDAR rescans of
    # redkitchen 34 -> 6: 15 RANSAC inliers and 2 degrees off before, FAILED after), so both
    # registrations are made and the better kept: adapting never turns a success into a failure.
    given = _match(src, dst, method, bundles, settings, watch.muted())
    watch.lap("registration with the bundles as given")
    with contextlib.ExitStack() as stack:        # a temporary folder lives while it is used
        folder = adapt_workdir or stack.enter_context(tempfile.TemporaryDirectory())
        adapted, note = adapted_bundles(method, bundles, source, target, settings.voxel,
                                        settings.radius, adapt, folder)
        watch.lap("adaptation")
        after = _match(src, dst, method, adapted, settings, watch)
    best, kept = _better(after, given)
    return dataclasses.replace(best, adaptation=note, kept=kept)


def _better(adapted: pipeline.Registration, given: pipeline.Registration):
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
    bundles = shipped.defaults()
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


def _match(src, dst, method, bundles, settings: pipeline.Settings,
           watch: pipeline.Stopwatch) -> pipeline.Registration:
    """The pipeline on two prepared fragments with ``method``'s descriptors: described share by
    share, or, for the pair vote, described once more in the voted frames."""
    from sphere_jax.features import methods
    if registry.resolve(method).kind != "voted":     # else described again in a voted frame
        describe = methods.descriptor_of_many(method, settings.radius, bundles)
        return pipeline.register(src, dst, describe, settings, method, watch)
    frames = methods.voted_frames(method, settings.radius, bundles)
    agree = functools.partial(consensus, max_distance=settings.distance, seed=settings.seed)
    screen = functools.partial(agree, iterations=SCREEN_ITERATIONS)
    inputs, _ = frames.describe_pairs({"target": dst, "source": src}, [("target", "source")],
                                      mutual_matches, agree, screen=screen)
    d_dst, d_src = inputs[("target", "source")]     # p_target = T p_source: (i, j)
    watch.lap("descriptors")
    return pipeline.register_described(src, dst, d_src, d_dst, settings, method, watch)


def _points(x, name):
    if isinstance(x, (str, bytes)) or hasattr(x, "__fspath__"):
        from sphere_jax.data.readers import io
        return io.read_points(x).points
    return checks.cloud(x, name)
