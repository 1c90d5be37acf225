"""Inference from Python: load a trained bundle, then orient or describe keypoints of a cloud.

    from sphere_jax import api
    compass = api.load_bundle("compass")          # the shipped one; or a bundle folder
    frames = compass.orient(points, keypoints, radius=0.3)        # [K, 3, 3], columns x̂ ŷ ẑ
    sound = api.load_bundle("runs/sound_mid/bundle")
    desc = sound.describe(points, keypoints, radius=0.3)          # [K, 512]

Patches are drawn with a fixed seed, jitted and vmapped over chunks of keypoints, so memory
stays bounded for any number of keypoints.
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import functools
import os

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import bundle as bundle_files
from sphere_jax import paths
from sphere_jax import models
from sphere_jax.data import patches as patch_lib
from sphere_jax.models import flare

FLARE_BATCH = jax.jit(jax.vmap(flare.flare))
DEFAULT_CHUNK = 256         # patches per call when neither the caller nor the bundle says


@dataclasses.dataclass
class Bundle:
    """A trained model: flax module, variables and the config it was trained with. What it can
    do (orient, describe) is its kind's :class:`~sphere_jax.models.spec.ModelSpec`."""
    model: object
    variables: dict
    config: ml_collections.ConfigDict

    @property
    def kind(self):
        return self.config.model

    @property
    def spec(self):
        return models.spec(self.kind)

    @property
    def chunk(self) -> int:
        """Patches per jitted call by default (``config.infer_chunk``; bundles written before
        it existed: :data:`DEFAULT_CHUNK`)."""
        return int(self.config.get("infer_chunk", DEFAULT_CHUNK))

    # ---- patches ----------------------------------------------------------------------------

    def patches(self, points, keypoints, radius=None, seed=0):
        """Unit-ball patches ``[K, N, 3]`` around ``keypoints`` (indices ``[K]`` or coordinates
        ``[K, 3]``)."""
        return extract_unit_patches(points, keypoints, float(radius or self.config.data.radius),
                                    self.config.data.n_points, seed)

    def _run(self, fn, x, chunk, workers):
        """:func:`run_chunked` with the bundle's chunk when the caller gives none."""
        return run_chunked(fn, x, self.chunk if chunk is None else chunk, workers)

    # ---- LRFs and descriptors ---------------------------------------------------------------

    def _can(self, what):
        if getattr(self.spec, what) is None:
            able = [k for k, s in models.SPECS.items() if getattr(s, what) is not None]
            raise ValueError(f"{what} needs a bundle of kind {', '.join(able)}; this one is "
                             f"{self.kind!r}")

    def orient(self, points, keypoints, radius=None, chunk=None, seed=0, workers=None):
        """LRFs ``[K, 3, 3]`` (Compass or SOUND bundles)."""
        self._can("orient")
        return self._run(self._orient_fn, self.patches(points, keypoints, radius, seed), chunk,
                         workers)

    def orient_patches(self, patches_KxNx3, chunk=None, workers=None):
        """LRFs ``[K, 3, 3]`` of ready-made unit patches (e.g. whole shapes, see
        :func:`sphere_jax.data.patches.unit_shapes`)."""
        self._can("orient")
        return self._run(self._orient_fn, np.asarray(patches_KxNx3, np.float32), chunk, workers)

    def describe(self, points, keypoints, radius=None, chunk=None, seed=0, frames=None,
                 workers=None):
        """Descriptors ``[K, D]``. LEAD: the SO(3) descriptor rotated to canonical pose by
        ``frames`` (``[K, 3, 3]``, e.g. from a Compass bundle) or, by default, FLARE; LEAD-PN:
        the code of the FLARE-oriented patch; SOUND: self-oriented."""
        self._can("describe")
        p = self.patches(points, keypoints, radius, seed)
        if not self.spec.describe_frames:
            return self._run(self._describe_fn, p, chunk, workers)
        if frames is None:
            frames = self._run(FLARE_BATCH, p, chunk, workers)
        frames = np.asarray(frames, np.float32)
        if frames.shape != (len(p), 3, 3):
            raise ValueError(f"frames must be [K, 3, 3] with K={len(p)}, got {frames.shape}")
        # Patches and frames travel as one array so that one run_chunked call splits both.
        both = np.concatenate([p.reshape(len(p), -1), frames.reshape(len(p), 9)], 1)
        return self._run(self._describe_fn, both, chunk, workers)

    # ---- jitted pieces ----------------------------------------------------------------------

    def __post_init__(self):
        spec, n = self.spec, self.config.data.n_points
        if spec.orient is not None:
            self._orient_fn = jax.jit(lambda x: spec.orient(self.model, self.variables, x))
        if spec.describe is not None and spec.describe_frames:
            def describe(x):
                pts, frames = x[:, :n * 3].reshape(-1, n, 3), x[:, n * 3:].reshape(-1, 3, 3)
                return spec.describe(self.model, self.variables, pts, frames)
            self._describe_fn = jax.jit(describe)
        elif spec.describe is not None:
            self._describe_fn = jax.jit(lambda x: spec.describe(self.model, self.variables, x,
                                                                None))


def run_chunked(fn, x, chunk=None, workers=None):
    """``fn`` over ``x`` in chunks of a fixed size (the last one padded), so a jitted ``fn``
    compiles once whatever the number of rows; ``workers`` chunks run at a time (default:
    :func:`default_workers`).

    Concurrent chunks are what uses a multi-core CPU here: XLA runs the loops of the fused
    inference path (:mod:`~sphere_jax.spherical.fused`) on one thread, so one chunk at a time
    keeps one core busy (LEAD 'paper' encoder on 2 cores: 19 ms per patch alone, 12 with two chunks).
    Each chunk in flight holds its own intermediates, so memory grows with ``workers``.
    """
    chunk = DEFAULT_CHUNK if chunk is None else int(chunk)
    workers = default_workers() if workers is None else int(workers)
    if chunk < 1 or workers < 1:
        raise ValueError(f"chunk and workers must be at least 1, got chunk={chunk}, "
                         f"workers={workers}")
    x = np.asarray(x)
    if len(x) == 0:
        return np.zeros((0,))

    def run(i):
        part = x[i:i + chunk]
        pad = chunk - len(part)
        if pad:
            part = np.concatenate([part, np.repeat(part[-1:], pad, 0)])
        return np.asarray(fn(jnp.asarray(part)))[:chunk - pad]

    starts = range(0, len(x), chunk)
    workers = min(len(starts), workers)
    if workers <= 1:
        return np.concatenate([run(i) for i in starts])
    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        return np.concatenate(list(pool.map(run, starts)))


def default_workers() -> int:
    """Chunks run at a time by :func:`run_chunked`: on a CPU backend one per core this process
    may use, at most 4 (each holds its chunk's intermediates: about 0.7 GB for LEAD 'paper' at
    256 patches); on an accelerator 1, since its own parallelism runs each chunk already."""
    if jax.default_backend() != "cpu":
        return 1
    return max(1, min(4, len(os.sched_getaffinity(0))))


def extract_unit_patches(points, keypoints, radius, n_points, seed=0):
    """Patches ``[K, n_points, 3]`` in units of ``radius`` around ``keypoints`` (indices ``[K]``
    or coordinates ``[K, 3]``); every keypoint must have a neighbour."""
    points = np.asarray(points, np.float32)
    keypoints = np.asarray(keypoints)
    if keypoints.ndim == 2 and keypoints.shape[1] == 3:          # coordinates: add as points
        idx = np.arange(len(points), len(points) + len(keypoints))
        points = np.concatenate([points, keypoints.astype(np.float32)])
        keypoints = idx
    got = patch_lib.extract_patches(points, keypoints, radius, n_points,
                                    np.random.default_rng(seed), min_points=1,
                                    tree=KDTree(points))
    if len(got.keypoints) != len(keypoints):
        missing = len(keypoints) - len(got.keypoints)
        raise ValueError(f"{missing} keypoint(s) have no neighbour within radius={radius}")
    return got.points / radius


def bundle_path(name_or_path) -> str:
    """A bundle folder, or the shipped bundle of a model kind (``'lead'``, ``'compass'``,
    ``'lead_pn'``, ``'sound'``, ``'compass_shapes'``; :data:`sphere_jax.paths.SHIPPED`)."""
    name = str(name_or_path)
    if name in paths.SHIPPED and not os.path.isdir(name):
        return paths.shipped_bundle(name, required=True)
    return name


def load_bundle(path) -> Bundle:
    """Load a bundle folder written at the end of training (:mod:`sphere_jax.bundle`), or a
    shipped one by model kind (:func:`bundle_path`)."""
    path = bundle_path(path)
    config = bundle_files.read_config(path)
    return Bundle(models.build(config), bundle_files.read_variables(path), config)


def cached_bundle(path) -> Bundle:
    """:func:`load_bundle`, once per bundle folder and process (the models compile once);
    a folder rewritten since (a new ``config.json``) is loaded again."""
    path = os.path.abspath(bundle_path(path))
    return _cached_bundle(path, bundle_files.stamp(path))


@functools.lru_cache(maxsize=16)
def _cached_bundle(path, _stamp):
    return load_bundle(path)


def orient_shapes(bundle, shapes_BxNx3):
    """Shapes turned into the canonical frame a Compass bundle (trained on whole shapes)
    gives them: ``(p − centre) @ F``, in the shapes' own units."""
    shapes_BxNx3 = np.asarray(shapes_BxNx3, np.float32)
    n = bundle.config.data.n_points
    rng = np.random.default_rng(0)
    pick = rng.integers(0, shapes_BxNx3.shape[1], n)            # the network's point count
    unit, centres = patch_lib.unit_shapes(shapes_BxNx3)
    frames = np.asarray(bundle.orient_patches(unit[:, pick], chunk=min(len(unit), 256)))
    return np.einsum("bnk,bkj->bnj", shapes_BxNx3 - centres, frames).astype(np.float32)
