"""The methods the benchmarks compare, by the names used in tables and configs.

Descriptors: ``describe(fragment) -> [K, D]`` for ``fragment.keypoints``; LRFs:
``orient(fragment, indices) -> [K, 3, 3]``. Hand-crafted ones use the exact neighbourhoods
(:mod:`neighbourhood`); learned ones load inference bundles (:mod:`sphere_jax.api`) and see
the resampled unit patches they were trained on.

=================  ==============================================================================
``fpfh``           FPFH (open3d), 33-d
``shot``           SHOT, 352-d, in the SHOT LRF
``spin``           Spin Images, 153-d
``usc``            Unique Shape Context, 1960-d, in the SHOT LRF
``lead``           LEAD's SO(3) descriptor turned to canonical pose by FLARE
``lead_compass``   the same, turned by the Compass LRF (needs a compass bundle)
``lead_pn``        LEAD-PN (PointNet on FLARE-oriented patches)
``sound``          SOUND, self-oriented
``lead_gt``        not a method but a diagnostic (registration only): LEAD turned by the ground
                   truth, so that corresponding patches share one canonical pose exactly
                   (:class:`GroundTruthTurned`) — how far a perfectly repeatable LRF would take it
=================  ==============================================================================

LRFs: ``flare`` (:func:`~sphere_jax.models.flare.flare` on the model's resampled patches, as LEAD
uses
it), ``shot``, ``toldi``, ``3dsn`` (3DSmoothNet's TOLDI variant), ``compass`` and ``sound``
(its Compass branch).
"""
from __future__ import annotations

import dataclasses
import warnings
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax import api
from sphere_jax import bundle as bundle_files
from sphere_jax.eval import descriptors, lrfs
from sphere_jax.eval.neighbourhood import radius_neighbourhoods
from sphere_jax.eval.scenes import Fragment
from sphere_jax.models import lead as lead_model

DESCRIPTORS = ("fpfh", "shot", "spin", "usc", "lead", "lead_compass", "lead_pn", "sound")
# Diagnostics that read each pair's ground truth: the registration benchmark only.
GROUND_TRUTH = ("lead_gt",)
LRFS = ("flare", "shot", "toldi", "3dsn", "compass", "sound")
# Which bundle each learned method needs.
BUNDLE_OF = {"lead": ("lead",), "lead_compass": ("lead", "compass"), "lead_pn": ("lead_pn",),
             "sound": ("sound",), "compass": ("compass",), "lead_gt": ("lead",)}
FLARE_POINTS = 1225


def _bundle(path):
    return api.cached_bundle(path)


def bundles_needed(names, bundles: dict):
    """The methods among ``names`` whose bundles are missing from ``bundles`` (kind -> path)."""
    return [n for n in names if any(not bundles.get(k) for k in BUNDLE_OF.get(n, ()))]


def _neighbourhoods(frag: Fragment, indices, radius):
    return radius_neighbourhoods(frag.points, frag.points[indices], radius, frag.tree)


def _masked(values_valid, fill):
    """Results of ``on_invalid='mask'`` with ``fill`` where a keypoint's support was too small
    to describe (stray sensor points): zero descriptors, like the hand-crafted ones' empty
    supports, and identity frames, which a repeatability test scores as it falls."""
    values, valid = values_valid
    values[~valid] = fill
    return values


def descriptor(name, radius, bundles=None, fpfh_radius=None, chunk=None):
    """``describe(fragment) -> [K, D]`` for method ``name`` with support ``radius`` (metres);
    ``bundles`` maps a model kind (lead, compass, lead_pn, sound) to a bundle path."""
    bundles = bundles or {}
    if name not in DESCRIPTORS:
        raise ValueError(f"unknown descriptor {name!r}; choose from {', '.join(DESCRIPTORS)}")
    missing = bundles_needed([name], bundles)
    if missing:
        raise ValueError(f"descriptor {name!r} needs bundle(s) {BUNDLE_OF[name]} in 'bundles'")
    if name == "fpfh":
        r = fpfh_radius or radius / 2
        return lambda f: descriptors.fpfh(f.points, f.normals, f.keypoints, r)
    if name == "shot":
        return lambda f: descriptors.shot(_neighbourhoods(f, f.keypoints, radius), f.normals)
    if name == "spin":
        return lambda f: descriptors.spin_image(_neighbourhoods(f, f.keypoints, radius),
                                                f.normals[f.keypoints])
    if name == "usc":
        return lambda f: descriptors.usc(_neighbourhoods(f, f.keypoints, radius), f.points,
                                         tree=f.tree)
    if name == "lead_compass":
        lead, compass = _bundle(bundles["lead"]), _bundle(bundles["compass"])

        def describe(f):
            frames = _masked(compass.orient(f.points, f.keypoints, radius=radius, chunk=chunk,
                                            on_invalid="mask"), np.eye(3))
            return _masked(lead.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                         frames=frames, on_invalid="mask"), 0)
        return describe
    model = _bundle(bundles[name])
    return lambda f: _masked(model.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                            on_invalid="mask"), 0)


@dataclasses.dataclass(frozen=True)
class GroundTruthTurned:
    """A descriptor that needs each pair's ground truth: ``describe(fragment) -> [K, D]`` as
    for a method, and ``turn(desc_j_KxD, t_4x4)``, which the benchmark applies to the second
    scan of each pair (p_i = T p_j) before matching."""
    describe: Callable
    turn: Callable

    def __call__(self, fragment):
        return self.describe(fragment)


@jax.jit
def _turn_maps(maps_KxD, rot_3x3):
    b2 = round(maps_KxD.shape[1] ** (1 / 3))
    frames = jnp.broadcast_to(rot_3x3.T, (maps_KxD.shape[0], 3, 3))
    return lead_model.canonical_descriptors(maps_KxD.reshape(-1, b2, b2, b2), frames)


def ground_truth_turned(name, radius, bundles=None, chunk=None) -> GroundTruthTurned:
    """``lead_gt``: LEAD's SO(3) maps left as they are (identity frames) on scan i of a pair and
    turned by the pair's rotation R on scan j. LEAD's map rotates with its patch, so a patch of
    scan j seen from scan i has the map of scan j rotated by R; turning it back by R gives both
    sides of every correct correspondence the same pose — the frame a perfectly repeatable LRF
    would give. Reads the ground truth: an upper bound that separates the descriptor's quality
    from its LRF's, never a method to compare."""
    bundles = bundles or {}
    if name not in GROUND_TRUTH:
        raise ValueError(f"unknown ground-truth diagnostic {name!r}; choose from "
                         f"{', '.join(GROUND_TRUTH)}")
    if bundles_needed([name], bundles):
        raise ValueError(f"diagnostic {name!r} needs bundle(s) {BUNDLE_OF[name]} in 'bundles'")
    lead = _bundle(bundles["lead"])

    def describe(f):
        eye = np.broadcast_to(np.eye(3, dtype=np.float32), (len(f.keypoints), 3, 3))
        return _masked(lead.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                     frames=eye, on_invalid="mask"), 0)

    def turn(desc_j_KxD, t_4x4):
        return np.asarray(_turn_maps(jnp.asarray(desc_j_KxD, jnp.float32),
                                     jnp.asarray(np.asarray(t_4x4)[:3, :3], jnp.float32)))
    return GroundTruthTurned(describe, turn)


def lrf(name, radius, bundles=None, chunk=None):
    """``orient(fragment, indices) -> [K, 3, 3]`` for LRF method ``name``."""
    bundles = bundles or {}
    if name not in LRFS:
        raise ValueError(f"unknown LRF {name!r}; choose from {', '.join(LRFS)}")
    if name == "flare":
        def orient(f, idx):
            p = api.extract_unit_patches(f.points, idx, radius, FLARE_POINTS)
            return api.run_chunked(api.FLARE_BATCH, p, chunk).reshape(-1, 3, 3)
        return orient
    if name == "shot":
        return lambda f, idx: lrfs.shot_lrf(_neighbourhoods(f, idx, radius))
    if name == "toldi":
        return lambda f, idx: lrfs.toldi_lrf(_neighbourhoods(f, idx, radius))
    if name == "3dsn":
        return lambda f, idx: lrfs.threedsn_lrf(_neighbourhoods(f, idx, radius))
    if bundles_needed([name], bundles):
        raise ValueError(f"LRF {name!r} needs a {name} bundle in 'bundles'")
    model = _bundle(bundles[name])
    return lambda f, idx: _masked(model.orient(f.points, idx, radius=radius, chunk=chunk,
                                               on_invalid="mask"), np.eye(3))


# ---- choice from an evaluation config ----------------------------------------------------------

def bundle_paths(config):
    """Kind -> bundle path: the config's defaults, ``config.bundle`` replacing its kind's."""
    paths = dict(config.bundles.to_dict())
    if config.bundle:
        if not bundle_files.is_bundle(config.bundle):
            raise FileNotFoundError(f"bundle={config.bundle!r} is not a bundle (no config.json)")
        paths[bundle_files.read_config(config.bundle).model] = config.bundle
    return paths


def chosen_methods(config, known, bundles):
    names = [m.strip() for m in config.methods.split(",") if m.strip()]
    bad = [m for m in names if m not in known]
    if bad:
        raise ValueError(f"methods {bad} unknown; choose from {', '.join(known)}")
    missing = bundles_needed(names, bundles)
    for m in missing:
        warnings.warn(f"method {m!r} skipped: no bundle for {BUNDLE_OF[m]} "
                      f"(set --config.bundle or --config.bundles.<kind>)", stacklevel=2)
    names = [m for m in names if m not in missing]
    if not names:
        raise ValueError("no method left to evaluate")
    return names
