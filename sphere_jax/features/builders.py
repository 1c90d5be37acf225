"""What each row of :mod:`registry` builds: descriptors, LRFs and ground-truth-frame
diagnostics of registration fragments (:class:`~sphere_jax.registration.fragments.Fragment`).

Builders take the support ``radius`` (metres), ``bundles`` (model kind -> bundle path) and
``chunk`` (patches per network call; None: each bundle's own) and return:

* a descriptor: ``describe_all([fragment, ...]) -> [[K, D], ...]`` for each fragment's
  ``keypoints``;
* an LRF: ``orient(fragment, indices) -> [K, 3, 3]``;
* a ground-truth-frame diagnostic: ``describe(fragment, rotation_3x3) -> [K, D]`` with every
  keypoint in that one frame.

Hand-crafted ones read exact neighbourhoods (:mod:`neighbourhood`); learned ones load inference
bundles (:mod:`sphere_jax.bundles.inference`) and see the resampled unit patches they were
trained on. A keypoint a network cannot describe (too few points in its support) gets a NaN
descriptor, which never matches, and an identity frame.
"""
from __future__ import annotations

import numpy as np

from sphere_jax import parallel
from sphere_jax.bundles import inference
from sphere_jax.data import supports
from sphere_jax.features import descriptors
from sphere_jax.features.neighbourhood import radius_neighbourhoods

FLARE_POINTS = 1225         # FLARE's frames on the patches LEAD is turned by


def neighbourhoods(frag, indices, radius):
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


# --- descriptors -------------------------------------------------------------------------

def per_fragment(describe, *options):
    """The builder of a hand-crafted descriptor ``describe(fragment, radius, **options) ->
    [K, D]``, one fragment at a time; ``options`` names the keyword options it takes
    (``fpfh_radius``)."""
    def build(radius, bundles=None, chunk=None, **given):
        kw = {k: given[k] for k in options if given.get(k) is not None}
        return lambda fragments: [describe(f, radius, **kw) for f in fragments]
    return build


def fpfh_of(f, radius, fpfh_radius=None):
    """FPFH of open3d on its own neighbourhood (half the support unless given)."""
    return descriptors.fpfh(f.points, f.normals, f.keypoints, fpfh_radius or radius / 2)


def shot_of(f, radius):
    return descriptors.shot(neighbourhoods(f, f.keypoints, radius), f.normals)


def spin_of(f, radius):
    return descriptors.spin_image(neighbourhoods(f, f.keypoints, radius),
                                  f.normals[f.keypoints])


def usc_of(f, radius):
    return descriptors.usc(neighbourhoods(f, f.keypoints, radius), f.points, tree=f.tree)


def network(kind):
    """The builder of the descriptor bundle ``bundles[kind]`` in its own frames: all the
    fragments in one stream of chunks
    (:meth:`~sphere_jax.bundles.inference.Bundle.describe_clouds`)."""
    def build(radius, bundles, chunk=None, **_):
        model = inference.cached_bundle(bundles[kind])
        return lambda fs: [masked(d, np.nan) for d in model.describe_clouds(
            [(f.points, f.keypoints) for f in fs], radius=radius, chunk=chunk,
            on_invalid="mask")]
    return build


def network_in_frames_of(kind, frame_kind, whitening=None):
    """The builder of descriptor bundle ``bundles[kind]`` turned to the frames of orienting
    bundle ``bundles[frame_kind]``, whitened by the descriptor bundle's whitening
    ``whitening`` (default: the one fitted in those frames, named ``frame_kind``) where it
    has one."""
    def build(radius, bundles, chunk=None, **_):
        model = inference.cached_bundle(bundles[kind])
        lrf = inference.cached_bundle(bundles[frame_kind])
        source = whitening or frame_kind
        whiten = source if source in model.whitenings else None

        def describe_all(fs):
            clouds = [(f.points, f.keypoints) for f in fs]
            return [masked(d, np.nan) for d in model.describe_clouds(
                clouds, radius=radius, chunk=chunk,
                frames=frames_for(model, lrf, clouds, radius, chunk), on_invalid="mask",
                whiten=whiten)]
        return describe_all
    return build


# --- ground-truth frames (diagnostics) ---------------------------------------------------

def shot_in_one_frame(radius, bundles=None, chunk=None):
    def describe(f, rot_3x3):
        return descriptors.shot(neighbourhoods(f, f.keypoints, radius), f.normals,
                                one_frame(rot_3x3, len(f.keypoints)))
    return describe


def network_in_one_frame(kind, whiten=None):
    """The builder of ``describe(fragment, rot_3x3)``: ``kind``'s descriptors turned to one
    frame for every keypoint (the ground truth's, for a diagnostic), whitened by the bundle's
    ``whiten`` whitening where it has one (so that it differs from a method in learned frames
    by its frames alone)."""
    def build(radius, bundles, chunk=None):
        model = inference.cached_bundle(bundles[kind])
        white = whiten if whiten in model.whitenings else None

        def describe(f, rot_3x3):
            return masked(model.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                         frames=one_frame(rot_3x3, len(f.keypoints)),
                                         on_invalid="mask", whiten=white), np.nan)
        return describe
    return build


# --- LRFs --------------------------------------------------------------------------------

def flare_lrf(radius, bundles=None, chunk=None):
    """FLARE (:func:`~sphere_jax.models.flare.flare`) on the model's resampled patches, as
    LEAD uses it."""
    def orient(f, idx):
        p = supports.extract_unit_patches(f.points, idx, radius, FLARE_POINTS)
        return parallel.run_chunked(inference.FLARE_BATCH, p, chunk).reshape(-1, 3, 3)
    return orient


def on_neighbourhoods(lrf, with_normals=False):
    """The builder of a hand-crafted LRF ``lrf(neighbourhoods[, normals]) -> [K, 3, 3]``."""
    def build(radius, bundles=None, chunk=None):
        if with_normals:
            return lambda f, idx: lrf(neighbourhoods(f, idx, radius), f.normals)
        return lambda f, idx: lrf(neighbourhoods(f, idx, radius))
    return build


def network_lrf(kind):
    """The builder of the frames of orienting bundle ``bundles[kind]``."""
    def build(radius, bundles, chunk=None):
        model = inference.cached_bundle(bundles[kind])
        return lambda f, idx: masked(model.orient(f.points, idx, radius=radius, chunk=chunk,
                                                  on_invalid="mask"), np.eye(3))
    return build
