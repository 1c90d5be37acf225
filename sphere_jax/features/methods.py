"""Every descriptor and LRF by the name tables, configs and ``sphere_jax.register`` use.

Descriptors: ``describe(fragment) -> [K, D]`` for ``fragment.keypoints``; LRFs:
``orient(fragment, indices) -> [K, 3, 3]``. Hand-crafted ones use the exact neighbourhoods
(:mod:`neighbourhood`); learned ones load inference bundles (:mod:`sphere_jax.api`) and see
the resampled unit patches they were trained on.

Names and their keys: :mod:`registry` (``lead@compass`` is ``lead_compass``).

LRFs: ``flare`` (:func:`~sphere_jax.models.flare.flare` on the model's resampled patches, as LEAD
uses
it), ``shot``, ``toldi``, ``3dsn`` (3DSmoothNet's TOLDI variant), ``compass`` and ``sound``
(its Compass branch).
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from sphere_jax import parallel
from sphere_jax.bundles import inference
from sphere_jax.data import supports
from sphere_jax.features import descriptors, lrfs, registry
from sphere_jax.features.neighbourhood import radius_neighbourhoods
from sphere_jax.registration.fragments import Fragment

# The keys of :mod:`registry` (grammar names resolve to them), by where they run.
DESCRIPTORS = registry.keys("descriptor")
GROUND_TRUTH = registry.keys("diagnostic")      # read each pair's ground truth: registration
VOTED = registry.keys("voted")                  # described per pair: registration only
LRFS = tuple(registry.LRFS)
# Which bundle each learned method and LRF needs.
BUNDLE_OF = {**{m.key: m.needs for m in registry.METHODS if m.needs},
             **{k: v for k, v in registry.LRFS.items() if v}}
FLARE_POINTS = 1225


def _bundle(path):
    return inference.cached_bundle(path)


def bundles_needed(names, bundles: dict):
    """The methods among ``names`` whose bundles are missing from ``bundles`` (kind -> path)."""
    return [n for n in names if any(not bundles.get(k) for k in BUNDLE_OF.get(n, ()))]


def neighbourhoods(frag: Fragment, indices, radius):
    """The exact supports of ``frag``'s points ``indices`` (radius in metres)."""
    return radius_neighbourhoods(frag.points, frag.points[indices], radius, frag.tree)


def one_frame(rotation_3x3, k):
    """``[k, 3, 3]`` float32: every keypoint in the same frame (a pair's shared pose)."""
    return np.broadcast_to(np.asarray(rotation_3x3, np.float32), (k, 3, 3))


def masked(values_valid, fill):
    """Results of ``on_invalid='mask'`` with ``fill`` where a keypoint's support was too small
    to describe (stray sensor points): NaN descriptors, which never match
    (:func:`~sphere_jax.registration.matching.mutual_matches`), and identity frames, which a
    repeatability test scores as it falls."""
    values, valid = values_valid
    values[~valid] = fill
    return values


def frames_for(model, lrf, clouds, radius, chunk=None):
    """What descriptor bundle ``model`` (LEAD) takes as ``frames`` for the LRFs of orienting
    bundle ``lrf`` (Compass) on ``clouds``: ``lrf`` itself where the two share their patches
    (the shipped pair, 1024 points: one draw, both networks in one call per chunk), else its
    frames as arrays, identity where a keypoint's support is too small."""
    if lrf.config.data.n_points == model.config.data.n_points \
            and lrf.min_support <= model.min_support:
        return lrf
    return [masked(o, np.eye(3)) for o in lrf.orient_clouds(clouds, radius=radius, chunk=chunk,
                                                            on_invalid="mask")]


def descriptor(name, radius, bundles=None, fpfh_radius=None, chunk=None):
    """``describe(fragment) -> [K, D]`` for method ``name`` with support ``radius`` (metres);
    ``bundles`` maps a model kind (lead, compass, lead_pn, sound) to a bundle path."""
    describe_all = descriptor_of_many(name, radius, bundles, fpfh_radius, chunk)
    return lambda f: describe_all([f])[0]


def descriptor_of_many(name, radius, bundles=None, fpfh_radius=None, chunk=None):
    """``describe_all([fragment, ...]) -> [[K, D], ...]`` for method ``name``, as
    :func:`descriptor`: a learned one describes all the fragments in one stream of chunks
    (:meth:`~sphere_jax.bundles.inference.Bundle.describe_clouds`), with the values of one at a
    time."""
    bundles = bundles or {}
    name = registry.resolve(name, ("descriptor",), "name").key
    missing = bundles_needed([name], bundles)
    if missing:
        raise ValueError(f"descriptor {name!r} needs bundle(s) {BUNDLE_OF[name]} in 'bundles'")
    if name not in BUNDLE_OF:                    # hand-crafted: no network, one at a time
        one = _hand_crafted(name, radius, fpfh_radius)
        return lambda fs: [one(f) for f in fs]
    if name == "lead_compass":
        lead, compass = _bundle(bundles["lead"]), _bundle(bundles["compass"])
        whiten = "compass" if "compass" in lead.whitenings else None

        def describe_all(fs):
            clouds = [(f.points, f.keypoints) for f in fs]
            return [masked(d, np.nan) for d in lead.describe_clouds(
                clouds, radius=radius, chunk=chunk,
                frames=frames_for(lead, compass, clouds, radius, chunk), on_invalid="mask",
                whiten=whiten)]
        return describe_all
    model = _bundle(bundles[name])
    return lambda fs: [masked(d, np.nan) for d in model.describe_clouds(
        [(f.points, f.keypoints) for f in fs], radius=radius, chunk=chunk, on_invalid="mask")]


def _hand_crafted(name, radius, fpfh_radius):
    """``describe(fragment)`` of a hand-crafted descriptor on the exact supports."""
    if name == "fpfh":
        r = fpfh_radius or radius / 2
        return lambda f: descriptors.fpfh(f.points, f.normals, f.keypoints, r)
    if name == "shot":
        return lambda f: descriptors.shot(neighbourhoods(f, f.keypoints, radius), f.normals)
    if name == "spin":
        return lambda f: descriptors.spin_image(neighbourhoods(f, f.keypoints, radius),
                                                f.normals[f.keypoints])
    return lambda f: descriptors.usc(neighbourhoods(f, f.keypoints, radius), f.points,
                                     tree=f.tree)


@dataclasses.dataclass(frozen=True)
class GroundTruthFrames:
    """A descriptor computed in frames read from each pair's ground truth (p_i = T p_j, R its
    rotation): ``describe_pair(fragment_i, fragment_j, t_4x4) -> (desc_i, desc_j)`` with every
    keypoint of scan i in the identity frame and every keypoint of scan j in Rᵀ, so that both
    sides of a correct correspondence share one pose exactly — the frame a perfectly
    repeatable LRF would give. It reads the ground truth: an upper bound that separates a
    descriptor's quality from its LRF's, never a method to compare."""
    describe_pair: Callable


def ground_truth_frames(name, radius, bundles=None, chunk=None) -> GroundTruthFrames:
    """``lead_gt`` (LEAD's SO(3) maps turned to those frames) or ``shot_gt`` (SHOT's
    histograms binned in them)."""
    bundles = bundles or {}
    name = registry.resolve(name, ("diagnostic",), "name").key
    if bundles_needed([name], bundles):
        raise ValueError(f"diagnostic {name!r} needs bundle(s) {BUNDLE_OF[name]} in 'bundles'")

    if name == "shot_gt":
        def describe(f, rot_3x3):
            return descriptors.shot(neighbourhoods(f, f.keypoints, radius), f.normals,
                                    one_frame(rot_3x3, len(f.keypoints)))
    else:
        lead = _bundle(bundles["lead"])

        def describe(f, rot_3x3):
            return masked(lead.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                         frames=one_frame(rot_3x3, len(f.keypoints)),
                                         on_invalid="mask"), np.nan)

    def describe_pair(f_i, f_j, t_4x4):
        return describe(f_i, np.eye(3)), describe(f_j, np.asarray(t_4x4)[:3, :3].T)
    return GroundTruthFrames(describe_pair)


def lrf(name, radius, bundles=None, chunk=None):
    """``orient(fragment, indices) -> [K, 3, 3]`` for LRF method ``name``."""
    bundles = bundles or {}
    if name not in LRFS:
        raise ValueError(f"unknown LRF {name!r}; choose from {', '.join(LRFS)}")
    if name == "flare":
        def orient(f, idx):
            p = supports.extract_unit_patches(f.points, idx, radius, FLARE_POINTS)
            return parallel.run_chunked(inference.FLARE_BATCH, p, chunk).reshape(-1, 3, 3)
        return orient
    if name == "shot":
        return lambda f, idx: lrfs.shot_lrf(neighbourhoods(f, idx, radius))
    if name == "toldi":
        return lambda f, idx: lrfs.toldi_lrf(neighbourhoods(f, idx, radius))
    if name == "3dsn":
        return lambda f, idx: lrfs.threedsn_lrf(neighbourhoods(f, idx, radius))
    if name == "gframes":
        return lambda f, idx: lrfs.gframes_lrf(neighbourhoods(f, idx, radius), f.normals)
    if bundles_needed([name], bundles):
        raise ValueError(f"LRF {name!r} needs a {name} bundle in 'bundles'")
    model = _bundle(bundles[name])
    return lambda f, idx: masked(model.orient(f.points, idx, radius=radius, chunk=chunk,
                                               on_invalid="mask"), np.eye(3))
