"""Every descriptor and LRF by the name tables, configs and ``sphere_jax.register`` use: the
rows of :mod:`registry` (``lead@compass`` is ``lead_compass``) built for a support radius
and bundles (what each builds: :mod:`builders`).

LRFs: ``flare`` (FLARE on the model's resampled patches, as LEAD uses it), ``shot``,
``toldi``, ``3dsn`` (3DSmoothNet's TOLDI variant), ``gframes``, ``compass`` and ``sound`` (its
Compass branch).
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from sphere_jax.features import registry
from sphere_jax.registration.vote import HYPOTHESES, TOL_DEG, VotedFrames


def bundles_needed(names, bundles: dict):
    """The methods or LRFs among ``names`` whose bundles are missing from ``bundles``
    (kind -> path)."""
    return [n for n in names if any(not bundles.get(k) for k in registry.needs(n))]


def _check_bundles(name, bundles, what):
    if bundles_needed([name], bundles):
        raise ValueError(f"{what} {name!r} needs bundle(s) {registry.needs(name)} in "
                         f"'bundles'")


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
    method = registry.resolve(name, ("descriptor",), "name")
    _check_bundles(method.key, bundles or {}, "descriptor")
    return method.build(radius, bundles or {}, chunk=chunk, fpfh_radius=fpfh_radius)


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
    method = registry.resolve(name, ("diagnostic",), "name")
    _check_bundles(method.key, bundles or {}, "diagnostic")
    describe = method.build(radius, bundles or {}, chunk=chunk)

    def describe_pair(f_i, f_j, t_4x4):
        return describe(f_i, np.eye(3)), describe(f_j, np.asarray(t_4x4)[:3, :3].T)
    return GroundTruthFrames(describe_pair)


def voted_frames(name, radius, bundles=None, chunk=None, tol_deg=TOL_DEG,
                 hypotheses=HYPOTHESES, box=True, whiten=True) -> VotedFrames:
    """``lead@compass+vote`` or ``shot+vote`` (keys ``lead_vote``, ``shot_vote``) with supports of
    ``radius`` metres; ``bundles`` maps lead and compass to bundle paths; ``hypotheses`` modes
    of each pair's vote are tried, and with ``box`` the box turns of the strongest. With
    ``whiten``, LEAD's maps are whitened as its bundle's statistics say (first pass: its
    ``compass`` whitening; second: :func:`~sphere_jax.bundles.whitening.rotation_averaged`);
    a bundle without a whitening matches raw maps."""
    method = registry.resolve(name, ("voted",), "name")
    _check_bundles(method.key, bundles or {}, "method")
    first, again = method.build(radius, bundles or {}, chunk=chunk, whiten=whiten)
    return VotedFrames(first, again, tol_deg, hypotheses, box)


def lrf(name, radius, bundles=None, chunk=None):
    """``orient(fragment, indices) -> [K, 3, 3]`` for LRF method ``name``."""
    if name not in registry.LRFS:
        raise ValueError(f"unknown LRF {name!r}; choose from {', '.join(registry.LRFS)}")
    if bundles_needed([name], bundles or {}):
        raise ValueError(f"LRF {name!r} needs a {name} bundle in 'bundles'")
    return registry.LRFS[name].build(radius, bundles or {}, chunk=chunk)
