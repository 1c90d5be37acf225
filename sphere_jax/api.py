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

import collections
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
from sphere_jax import checks
from sphere_jax import models, parallel, paths
from sphere_jax.data import o3d_convert
from sphere_jax.data import patches as patch_lib
from sphere_jax.models import flare

FLARE_BATCH = jax.jit(jax.vmap(flare.flare))
DEFAULT_CHUNK = 256         # patches per call when neither the caller nor the bundle says
# Fewest support points a keypoint needs: below it the N points of a patch are drawn from a
# handful (one neighbour gave N copies of one point) and no frame or descriptor means anything.
MIN_SUPPORT = 16


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

    @property
    def min_support(self) -> int:
        """The fewest support points a keypoint needs to be oriented or described
        (``config.data.min_support``; default :data:`MIN_SUPPORT`)."""
        return int(self.config.data.get("min_support", MIN_SUPPORT))

    # ---- patches ----------------------------------------------------------------------------

    def supports(self, points, keypoints, radius=None, seed=0) -> "SupportStream":
        """The unit-ball patches around ``keypoints`` (indices ``[K]`` or coordinates
        ``[K, 3]``), drawn chunk by chunk (:class:`SupportStream`)."""
        return SupportStream(points, keypoints, self._radius(radius),
                             self.config.data.n_points, seed, self.min_support)

    def patches(self, points, keypoints, radius=None, seed=0):
        """All unit-ball patches ``[K, N, 3]`` at once (every keypoint must have
        :attr:`min_support` support points); :meth:`orient` and :meth:`describe` stream them."""
        return extract_unit_patches(points, keypoints, self._radius(radius),
                                    self.config.data.n_points, seed,
                                    self.min_support)

    def _run(self, fn, x, chunk, workers):
        """:func:`run_chunked` with the bundle's chunk when the caller gives none."""
        return run_chunked(fn, x, self._chunk(chunk), workers)

    def _radius(self, radius):
        """The given support radius (checked, never replaced) or the bundle's training one."""
        return checks.positive(radius, "radius", default=float(self.config.data.radius))

    def _chunk(self, chunk):
        return checks.positive(chunk, "chunk", integer=True, default=self.chunk)

    # ---- LRFs and descriptors ---------------------------------------------------------------

    def _can(self, what):
        if getattr(self.spec, what) is None:
            able = [k for k, s in models.SPECS.items() if getattr(s, what) is not None]
            raise checks.InputError("bundle", f"of kind {', '.join(able)} to {what}",
                                    f"one of kind {self.kind!r}")

    def orient(self, points, keypoints, radius=None, chunk=None, seed=0, workers=None,
               on_invalid="raise"):
        """LRFs ``[K, 3, 3]`` (Compass or SOUND bundles). ``on_invalid``: what a keypoint with
        fewer than :attr:`min_support` support points gets — ``"raise"`` an error,
        ``"mask"`` NaN rows, the result then being ``(frames, valid [K] bool)``."""
        self._can("orient")
        checks.choice(on_invalid, "on_invalid", ON_INVALID)
        stream = self.supports(points, keypoints, radius, seed)
        stream.check(on_invalid)
        out = stream_chunked(self._orient_fn, stream.make, stream.n, self._chunk(chunk),
                             workers)
        return stream.scatter(out, (3, 3), on_invalid)

    def orient_patches(self, patches_KxNx3, chunk=None, workers=None):
        """LRFs ``[K, 3, 3]`` of ready-made unit patches (e.g. whole shapes, see
        :func:`sphere_jax.data.patches.unit_shapes`)."""
        self._can("orient")
        p = np.asarray(patches_KxNx3)
        if p.ndim != 3 or p.shape[2] != 3 or p.dtype.kind not in "iuf" \
                or not np.isfinite(p).all():
            raise checks.InputError("patches_KxNx3", "finite float patches [K, N, 3]",
                                    checks.shown(p) + ("" if p.dtype.kind not in "iuf" or
                                                       np.isfinite(p).all() else
                                                       " with non-finite values"))
        return self._run(self._orient_fn, p.astype(np.float32), chunk, workers)

    def describe(self, points, keypoints, radius=None, chunk=None, seed=0, frames=None,
                 workers=None, on_invalid="raise", as_open3d=False):
        """Descriptors ``[K, D]``. LEAD: the SO(3) descriptor rotated to canonical pose by
        ``frames`` (``[K, 3, 3]`` rotations, e.g. from a Compass bundle) or, by default,
        FLARE; LEAD-PN: the code of the FLARE-oriented patch; SOUND: self-oriented.
        ``on_invalid`` as in :meth:`orient`; ``as_open3d``: an
        ``open3d.pipelines.registration.Feature`` instead (open3d's RANSAC and FGR take it)."""
        out = self._describe(points, keypoints, radius, chunk, seed, frames, workers,
                             on_invalid)
        if not as_open3d:
            return out
        if on_invalid == "mask":
            return open3d_feature(out[0]), out[1]
        return open3d_feature(out)

    def _describe(self, points, keypoints, radius, chunk, seed, frames, workers, on_invalid):
        self._can("describe")
        checks.choice(on_invalid, "on_invalid", ON_INVALID)
        stream = self.supports(points, keypoints, radius, seed)
        if frames is not None:
            if not self.spec.describe_frames:
                raise checks.InputError("frames", f"None for a {self.kind} bundle (it orients "
                                        "its patches itself)", checks.shown(frames))
            stream.frames = checks.rotations(frames, stream.k)
        stream.check(on_invalid)
        out = stream_chunked(self._describe_fn, stream.make, stream.n, self._chunk(chunk),
                             workers)
        if stream.n == 0:                         # nothing to describe: the width still counts
            unit = jax.ShapeDtypeStruct((1, self.config.data.n_points, 3), jnp.float32)
            out = np.zeros((0, *jax.eval_shape(self._describe_fn, unit).shape[1:]))
        return stream.scatter(out, None, on_invalid)

    # ---- jitted pieces ----------------------------------------------------------------------

    def __post_init__(self):
        spec = self.spec
        if spec.orient is not None:
            self._orient_fn = jax.jit(lambda p: spec.orient(self.model, self.variables, p))
        if spec.describe is not None and spec.describe_frames:
            def describe(p, frames=None):
                frames = FLARE_BATCH(p) if frames is None else frames
                return spec.describe(self.model, self.variables, p, frames)
            self._describe_fn = jax.jit(describe)
        elif spec.describe is not None:
            self._describe_fn = jax.jit(lambda p: spec.describe(self.model, self.variables, p,
                                                                None))


ON_INVALID = ("raise", "mask")


class SupportStream:
    """The supports of ``K`` keypoints (indices into ``points`` or coordinates, which are
    queried, not added to the cloud), counted at once and drawn chunk by chunk: memory is that
    of one chunk's neighbour lists, whatever K. Only the keypoints with at least
    ``min_support`` points (the centre excluded) are drawn: ``rows`` of them, ``n`` in all.
    :meth:`make` must be called on consecutive row ranges in order (the patch sampling is one
    random stream, so the chunking does not change the patches)."""

    def __init__(self, points, keypoints, radius, n_points, seed, min_support):
        self.points = checks.cloud(points)
        idx, coords = checks.keypoints(keypoints, len(self.points))
        self.centres = self.points[idx] if coords is None else coords
        self.radius, self.n_points, self.min_support = radius, n_points, min_support
        self.tree = KDTree(self.points)
        if len(self.centres):
            # Points at the centre give no direction: they are not support.
            self.counts = (self.tree.query_radius(self.centres, radius, count_only=True)
                           - self.tree.query_radius(self.centres, 0.0, count_only=True))
        else:
            self.counts = np.zeros(0, np.int64)
        self.valid = self.counts >= min_support
        self.rows = np.flatnonzero(self.valid)
        self.k, self.n = len(self.centres), len(self.rows)
        self.frames = None
        self._rng = np.random.default_rng(seed)

    def check(self, on_invalid):
        if on_invalid == "raise" and not self.valid.all():
            first = int(np.argmin(self.valid))
            raise checks.InputError(
                "keypoints", f"supports (radius={self.radius:g}) of at least {self.min_support} "
                f"points", f"{self.k - self.n} of {self.k} with fewer (the first, keypoint "
                f"{first}, has {int(self.counts[first])}); pass on_invalid='mask' to get a "
                f"valid mask instead", verb="have")

    def make(self, start, stop):
        """Inputs of rows ``start:stop``: unit patches ``[k, N, 3]`` (and frames)."""
        rows = self.rows[start:stop]
        got = patch_lib.patches_around(self.points, self.centres[rows], self.radius,
                                       self.n_points, self._rng, 1, self.tree)
        unit = got.points / np.float32(self.radius)
        return (unit,) if self.frames is None else (unit, self.frames[rows])

    def scatter(self, values, row_shape, on_invalid):
        """The ``n`` computed rows back at their keypoints, NaN at the invalid ones."""
        values = np.asarray(values, np.float32)
        if values.ndim == 1 and row_shape is not None:        # no row computed
            values = values.reshape(0, *row_shape)
        out = np.full((self.k, *values.shape[1:]), np.nan, np.float32)
        out[self.rows] = values
        return out if on_invalid == "raise" else (out, self.valid.copy())


def run_chunked(fn, x, chunk=None, workers=None):
    """``fn`` over the rows of ``x`` in chunks (:func:`stream_chunked`)."""
    x = np.asarray(x)
    return stream_chunked(fn, lambda a, b: (x[a:b],), len(x), chunk, workers)


def stream_chunked(fn, make, n, chunk=None, workers=None):
    """``fn(*make(a, b))`` over rows ``0..n`` in chunks of a fixed size (the last one padded),
    so a jitted ``fn`` compiles once whatever ``n``; one thread prepares the next chunk's
    inputs (in order) while ``workers`` chunks run (default :func:`default_workers`), so at
    most ``workers + 1`` chunks exist at a time.

    Concurrent chunks are what uses a multi-core CPU here: XLA runs the loops of the fused
    inference path (:mod:`~sphere_jax.spherical.fused`) on one thread, so one chunk at a time
    keeps one core busy (LEAD 'paper' encoder on 2 cores: 19 ms per patch alone, 12 with two chunks).
    Each chunk in flight holds its own intermediates, so memory grows with ``workers``.
    """
    chunk = checks.positive(DEFAULT_CHUNK if chunk is None else chunk, "chunk", integer=True)
    workers = checks.positive(default_workers() if workers is None else workers, "workers",
                              integer=True)
    if n == 0:
        return np.zeros((0,))
    rows_on = chunk_sharding()
    if rows_on is not None:                  # every device takes an equal block of each chunk
        chunk = -(-chunk // rows_on.mesh.size) * rows_on.mesh.size
    starts = list(range(0, n, chunk))

    def prepare(a):
        parts = make(a, min(a + chunk, n))
        rows = len(parts[0])
        pad = chunk - rows
        if pad:
            parts = tuple(np.concatenate([p, np.repeat(p[-1:], pad, 0)]) for p in parts)
        return parts, rows

    def compute(parts, rows):
        put = jnp.asarray if rows_on is None else lambda p: jax.device_put(p, rows_on)
        return np.asarray(fn(*(put(p) for p in parts)))[:rows]

    out, running = [], collections.deque()
    workers = min(len(starts), workers)
    with concurrent.futures.ThreadPoolExecutor(1) as prep, \
            concurrent.futures.ThreadPoolExecutor(workers) as pool:
        ahead = prep.submit(prepare, starts[0])
        for j in range(len(starts)):
            parts, rows = ahead.result()
            if j + 1 < len(starts):
                ahead = prep.submit(prepare, starts[j + 1])
            running.append(pool.submit(compute, parts, rows))
            if len(running) >= workers:
                out.append(running.popleft().result())
        out.extend(f.result() for f in running)
    return np.concatenate(out)


def chunk_sharding():
    """With more than one local device (GPUs, TPU cores, or CPU host devices forced by
    ``XLA_FLAGS``): chunks split on their first axis across all of them, so the jitted
    network runs on every device at once (one SPMD program, :mod:`sphere_jax.parallel`'s
    axis); None with one device. Only this process's devices: in a multi-process run each
    process describes its own scans."""
    devices = jax.local_devices()
    if len(devices) < 2:
        return None
    return jax.sharding.NamedSharding(jax.sharding.Mesh(np.array(devices), (parallel.AXIS,)),
                                      jax.sharding.PartitionSpec(parallel.AXIS))


def default_workers() -> int:
    """Chunks run at a time by :func:`run_chunked`: on a CPU backend one per core this process
    may use, at most 4 (each holds its chunk's intermediates: about 0.7 GB for LEAD 'paper' at
    256 patches); on an accelerator 1, since its own parallelism runs each chunk already."""
    if jax.default_backend() != "cpu":
        return 1
    return max(1, min(4, len(os.sched_getaffinity(0))))


def extract_unit_patches(points, keypoints, radius, n_points, seed=0, min_support=1):
    """All patches ``[K, n_points, 3]`` at once, in units of ``radius``, around ``keypoints``
    (indices ``[K]`` or coordinates ``[K, 3]``); every keypoint must have ``min_support``
    support points."""
    stream = SupportStream(points, keypoints, checks.positive(radius, "radius"),
                           checks.positive(n_points, "n_points", integer=True), seed,
                           min_support)
    stream.check("raise")
    return stream.make(0, stream.n)[0]


def open3d_feature(desc_KxD):
    """Descriptors as the ``open3d.pipelines.registration.Feature`` that open3d's RANSAC and
    FGR take (:func:`sphere_jax.data.o3d_convert.feature`)."""
    return o3d_convert.feature(desc_KxD)


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
    try:
        model = models.build(config)
    except Exception as e:                    # an unknown kind, a field the module lacks
        raise checks.BundleError(path, f"its config builds no model "
                                       f"({bundle_files.first_line(e)})") from None
    variables = bundle_files.read_variables(path)
    key = jax.random.PRNGKey(0)
    x = jax.ShapeDtypeStruct((1, config.data.n_points, 3), jnp.float32)
    expected = jax.eval_shape(functools.partial(model.init, train=False),
                              {"params": key, "dropout": key}, x)
    bundle_files.check_fits(path, variables, {k: expected.get(k, {}) for k in variables})
    return Bundle(model, variables, config)


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
