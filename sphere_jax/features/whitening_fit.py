"""Fitting a descriptor bundle's whitening (:mod:`whitening`) on its own training scans.

    python -m experiments.whiten --bundle=sphere_jax/weights/lead_mid/bundle

describes ``keypoints`` random keypoints on each of ``scans`` scans spread over the bundle's
``config.data.root`` (the scans it trained on: never an evaluation scene), at its training
voxel and radius, and fits one whitening per frame source: ``default`` (the kind's own frames)
and, for LEAD, ``compass`` (in the frames of a Compass bundle).
"""
from __future__ import annotations

import time

import numpy as np
from tqdm.auto import tqdm

from sphere_jax import checks, paths
from sphere_jax.bundles import inference, model_card, store
from sphere_jax.data import scan_roots
from sphere_jax.features import builders
from sphere_jax.bundles import whitening

SCANS, KEYPOINTS = 12, 1500     # 18 000 keypoints: 35× LEAD's 512 dimensions


def training_clouds(config, scans=SCANS, keypoints=KEYPOINTS, seed=0, progress=True):
    """``([(points, keypoints)], scan paths)``: ``scans`` scans evenly spread over
    ``config.data.root``'s, on its voxel grid, ``keypoints`` random ones each."""
    found = scan_roots.scan_paths(config.data.root)
    picked = [found[i] for i in np.unique(np.linspace(0, len(found) - 1, scans).round()
                                          .astype(int))]
    clouds = []
    for i, path in enumerate(tqdm(picked, desc="training scans", disable=not progress)):
        points = scan_roots.load_scan(path, config.data.voxel)
        rng = np.random.default_rng([seed, i])
        clouds.append((points, rng.choice(len(points), min(keypoints, len(points)),
                                          replace=False)))
    return clouds, picked


def descriptor_bundle(bundle_arg):
    """``(folder, Bundle)`` of a bundle argument that must describe (checked, named); cached,
    so that checking the argument first does not load the bundle twice."""
    path = inference.bundle_path(bundle_arg)
    model = inference.cached_bundle(path)
    if model.spec.describe is None:
        raise checks.InputError("bundle", "a descriptor bundle (lead, lead_pn, sound)",
                                f"one of kind {model.kind!r}")
    return path, model


def frame_bundle(bundle_arg):
    """The Compass-like bundle of a ``compass`` argument: one that orients (checked, named)."""
    model = inference.cached_bundle(inference.bundle_path(bundle_arg))
    if model.spec.orient is None:
        raise checks.InputError("compass", "a bundle that orients (compass)",
                                f"one of kind {model.kind!r}")
    return model


def fit_if_descriptor(bundle_dir, compass=None, command=None, progress=True):
    """:func:`fit_bundle` with the default scans and keypoints when ``bundle_dir`` describes
    (LEAD, LEAD-PN, SOUND); None for other kinds. What ``experiments.train`` runs on the
    bundle it writes."""
    if inference.cached_bundle(inference.bundle_path(bundle_dir)).spec.describe is None:
        return None
    return fit_bundle(bundle_dir, compass, command=command, progress=progress)


def keep_from(source_dir, bundle_dir):
    """Copy the whitenings of bundle ``source_dir`` into ``bundle_dir`` (its adapted copy),
    the statement naming where they came from; returns the sources copied.

    Why an adaptation keeps them rather than fitting new ones on the user's scans: on the
    bunny's ten scans, statistics fitted there gave LEAD-PN (whose adaptation kept its
    weights) an inlier ratio of 0.235 against 0.281 with its training rooms' and the adapted
    LEAD (Compass) 0.080 against 0.092 (registration recall 0.50 against 0.55) — a few scans
    of one object vary along fewer directions than the rooms, and whitening blows up the
    rest (docs/training.md)."""
    source_dir = inference.bundle_path(source_dir)
    kept = whitening.load(source_dir)
    if kept:
        statement = {name: dict(fit, kept_from=paths.relative(source_dir))
                     for name, fit in whitening.read_statement(source_dir).items()}
        whitening.save(bundle_dir, kept, statement)
        model_card.render(bundle_dir)
    return sorted(kept)


def fit_bundle(bundle_dir, compass=None, scans=SCANS, keypoints=KEYPOINTS, command=None,
               progress=True):
    """Fit and save the whitenings of the descriptor bundle ``bundle_dir`` (``compass``: a
    Compass bundle for LEAD's ``compass`` source; None: the shipped one) and render its model
    card again. Returns ``{source: keypoints used}``."""
    bundle_dir, model = descriptor_bundle(bundle_dir)
    frame_paths = {"compass": inference.bundle_path(compass or "compass")} \
        if model.spec.describe_frames else {}
    frame_bundles = {k: frame_bundle(p) for k, p in frame_paths.items()}
    start = time.perf_counter()
    clouds, picked = training_clouds(model.config, scans, keypoints, progress=progress)
    radius = float(model.config.data.radius)
    sources = {"default": None}
    for name, lrf in frame_bundles.items():
        sources[name] = builders.frames_for(model, lrf, clouds, radius)
    fitted, statement, used = {}, {}, {}
    for name, frames in sources.items():
        # On supports drawn as training draws them, not as describing does: fitted on even
        # draws, the shipped LEAD's and LEAD-PN's whitenings matched 1-1.5 % less often on
        # the redkitchen pairs (docs/training.md, "Descriptor whitening").
        out = model.describe_clouds(clouds, radius, frames=frames, on_invalid="mask",
                                    whiten=None, draw="random")
        desc = np.concatenate([d[v] for d, v in out])
        if len(desc) <= desc.shape[1]:
            raise checks.InputError(
                "scans", f"enough to describe more keypoints than the descriptor's "
                f"{desc.shape[1]} values (more scans or --keypoints)",
                f"{len(desc)} described keypoints on {len(picked)} scan(s)")
        fitted[name] = whitening.fit(desc)
        used[name] = len(desc)
        statement[name] = {
            "scans": [paths.portable(p) for p in picked], "keypoints": len(desc),
            "voxel": float(model.config.data.voxel), "radius": radius,
            "dimensions_kept": int(fitted[name].axes.shape[1]), "eps": whitening.EPS,
            "frames": ("the kind's own" if name == "default" else
                       f"{name} bundle {paths.relative(frame_paths[name])} "
                       f"({store.fingerprint(frame_paths[name])})"),
            "command": command or ""}
    whitening.save(bundle_dir, fitted, statement)
    model_card.render(bundle_dir)                    # the card states what was fitted
    if progress:
        print(f"whitenings {', '.join(used)} fitted on {sum(used.values())} keypoints of "
              f"{len(picked)} training scans in {time.perf_counter() - start:.0f} s")
    return used
