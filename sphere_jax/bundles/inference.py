"""Inference from Python: load a trained bundle, then orient or describe keypoints of a cloud.

    from sphere_jax.bundles import inference
    compass = inference.load_bundle("compass")          # the shipped one; or a bundle folder
    frames = compass.orient(points, keypoints, radius=0.3)        # [K, 3, 3], columns x̂ ŷ ẑ
    sound = inference.load_bundle("runs/sound_mid/bundle")
    desc = sound.describe(points, keypoints, radius=0.3)          # [K, 512]

Patches are drawn with a fixed seed, jitted and vmapped over chunks of keypoints, so memory
stays bounded for any number of keypoints.
"""
from __future__ import annotations

import dataclasses
import functools
import os

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from sphere_jax import checks, models
from sphere_jax.bundles import store
from sphere_jax.bundles import whitening as whitening_lib
from sphere_jax.data import o3d_convert
from sphere_jax.data import patches as patch_lib
from sphere_jax.data.supports import (DRAW, MIN_SUPPORT, StreamChain, SupportStream,
                                      extract_unit_patches)
from sphere_jax.models import flare, shipped
from sphere_jax.parallel import DEFAULT_CHUNK, in_slices, run_chunked, stream_chunked

FLARE_BATCH = jax.jit(jax.vmap(flare.flare))


@dataclasses.dataclass
class Bundle:
    """A trained model: flax module, variables and the config it was trained with. What it can
    do (orient, describe) is its kind's :class:`~sphere_jax.models.spec.ModelSpec`."""
    model: object
    variables: dict
    config: ml_collections.ConfigDict
    # frame source -> descriptor whitening fitted on the training scans (features/whitening)
    whitenings: dict = dataclasses.field(default_factory=dict)

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

    def supports(self, points, keypoints, radius=None, seed=0, draw=DRAW) -> "SupportStream":
        """The unit-ball patches around ``keypoints`` (indices ``[K]`` or coordinates
        ``[K, 3]``), drawn chunk by chunk (:class:`SupportStream`; ``draw``: one of
        :data:`~sphere_jax.data.patches.DRAWS`)."""
        return SupportStream(points, keypoints, self._radius(radius),
                             self.config.data.n_points, seed, self.min_support, draw)

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
        return self.orient_clouds([(points, keypoints)], radius, chunk, seed, workers,
                                  on_invalid)[0]

    def orient_clouds(self, clouds, radius=None, chunk=None, seed=0, workers=None,
                      on_invalid="raise"):
        """:meth:`orient` of several clouds ``[(points, keypoints), ...]`` in one stream of
        chunks, so the cores stay busy from one cloud to the next: a list with each cloud's
        result, the same as :meth:`orient` gives it alone."""
        self._can("orient")
        checks.choice(on_invalid, "on_invalid", ON_INVALID)
        chain = self._chain(clouds, radius, seed, on_invalid)
        out = stream_chunked(self._orient_fn, chain.make, chain.n, self._chunk(chunk), workers)
        return [s.scatter(o, (3, 3), on_invalid) for s, o in zip(chain.streams, chain.split(out))]

    def orient_modes(self, points, keypoints, k, radius=None, chunk=None, seed=0, workers=None,
                     on_invalid="raise"):
        """Frame hypotheses ``[K, k, 3, 3]``: the ``k`` strongest modes of a Compass bundle's
        SO(3) map at each keypoint, strongest first (the first is :meth:`orient`'s);
        ``on_invalid`` as :meth:`orient`."""
        return self.orient_modes_clouds([(points, keypoints)], k, radius, chunk, seed,
                                        workers, on_invalid)[0]

    def orient_modes_clouds(self, clouds, k, radius=None, chunk=None, seed=0, workers=None,
                            on_invalid="raise"):
        """:meth:`orient_modes` of several clouds in one stream of chunks."""
        self._can("orient_modes")
        k = checks.positive(k, "k", integer=True)
        checks.choice(on_invalid, "on_invalid", ON_INVALID)
        chain = self._chain(clouds, radius, seed, on_invalid)
        if k not in self._modes_fns:
            spec = self.spec
            self._modes_fns[k] = jax.jit(in_slices(
                lambda p: spec.orient_modes(self.model, self.variables, p, k), spec.infer_slice))
        out = stream_chunked(self._modes_fns[k], chain.make, chain.n, self._chunk(chunk),
                             workers)
        return [s.scatter(o, (k, 3, 3), on_invalid) for s, o in zip(chain.streams,
                                                                    chain.split(out))]

    def _chain(self, clouds, radius, seed, on_invalid, frames=None, draw=DRAW):
        """The clouds' :class:`SupportStream` chained (:class:`StreamChain`), ``frames``
        (one ``[K, 3, 3]`` per cloud, or None) attached, each checked for ``on_invalid``."""
        if isinstance(clouds, (str, bytes, np.ndarray)) or not hasattr(clouds, "__len__") \
                or not len(clouds) or any(not isinstance(c, (tuple, list)) or len(c) != 2
                                          for c in clouds):
            raise checks.InputError("clouds", "a non-empty list of (points, keypoints) pairs",
                                    checks.shown(clouds))
        if frames is not None and (not isinstance(frames, (tuple, list))
                                   or len(frames) != len(clouds)):
            raise checks.InputError("frames", f"a list of one [K, 3, 3] array per cloud "
                                    f"({len(clouds)})", checks.shown(frames))
        streams = []
        for j, (points, keypoints) in enumerate(clouds):
            stream = self.supports(points, keypoints, radius, seed, draw)
            if frames is not None:
                if not self.spec.describe_frames:
                    raise checks.InputError("frames", f"None for a {self.kind} bundle (it "
                                            "orients its patches itself)",
                                            checks.shown(frames[j]))
                stream.frames = checks.rotations(frames[j], stream.k)
            stream.check(on_invalid)
            streams.append(stream)
        return StreamChain(streams)

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
                 workers=None, on_invalid="raise", as_open3d=False, whiten="auto"):
        """Descriptors ``[K, D]``. LEAD: the SO(3) descriptor rotated to canonical pose by
        ``frames`` — ``[K, 3, 3]`` rotations, or a Compass bundle that orients the very
        patches LEAD describes in the same call (:meth:`describe_clouds`) — or, by default,
        FLARE; LEAD-PN: the code of the FLARE-oriented patch; SOUND: self-oriented.
        ``whiten``: the bundle's whitening for the frames used (:mod:`~sphere_jax.features.
        whitening`) — ``"auto"`` its ``default`` one when ``frames`` is None and none when
        frames are given, ``"compass"`` the one fitted in Compass frames, None raw values.
        ``on_invalid`` as in :meth:`orient`; ``as_open3d``: an
        ``open3d.pipelines.registration.Feature`` instead (open3d's RANSAC and FGR take it)."""
        out = self.describe_clouds([(points, keypoints)], radius, chunk, seed,
                                   frames if frames is None or isinstance(frames, Bundle)
                                   else [frames], workers, on_invalid, whiten)[0]
        if not checks.flag(as_open3d, "as_open3d"):
            return out
        if on_invalid == "mask":
            return open3d_feature(out[0]), out[1]
        return open3d_feature(out)

    def describe_clouds(self, clouds, radius=None, chunk=None, seed=0, frames=None,
                        workers=None, on_invalid="raise", whiten="auto", draw=DRAW):
        """:meth:`describe` of several clouds ``[(points, keypoints), ...]`` in one stream of
        chunks, as :meth:`orient_clouds`. ``frames``: None, one ``[K, 3, 3]`` per cloud, or
        an orienting bundle (Compass, same ``data.n_points``) run on each chunk's patches in
        the same jitted call as the descriptor: one support draw and one stream for both
        networks, the values of orienting first and describing in those frames after.
        ``draw``: how supports are drawn (:data:`~sphere_jax.data.supports.DRAW`)."""
        self._can("describe")
        checks.choice(on_invalid, "on_invalid", ON_INVALID)
        white = self._whitening(whiten, frames is not None)
        fn = self._describe_fn
        if isinstance(frames, Bundle):
            fn, frames = self._framed_by(frames), None
        chain = self._chain(clouds, radius, seed, on_invalid, frames, draw)
        out = stream_chunked(fn, chain.make, chain.n, self._chunk(chunk), workers)
        if chain.n == 0:                          # nothing to describe: the width still counts
            unit = jax.ShapeDtypeStruct((1, self.config.data.n_points, 3), jnp.float32)
            out = np.zeros((0, *jax.eval_shape(fn, unit).shape[1:]))
        elif white is not None:
            out = white.apply(out)
        return [s.scatter(o, None, on_invalid) for s, o in zip(chain.streams, chain.split(out))]

    def _framed_by(self, lrf: "Bundle"):
        """The jitted ``patches -> descriptors`` in the frames ``lrf`` gives the same patches
        (one per orienting bundle, kept with it)."""
        if not self.spec.describe_frames:
            raise checks.InputError("frames", f"None for a {self.kind} bundle (it orients its "
                                    "patches itself)", f"a {lrf.kind} bundle")
        lrf._can("orient")
        if lrf.config.data.n_points != self.config.data.n_points \
                or lrf.min_support > self.min_support:
            raise checks.InputError(
                "frames", f"an orienting bundle whose patches are this {self.kind} bundle's "
                f"(data.n_points {self.config.data.n_points}, min_support at most "
                f"{self.min_support}); pass its frames as arrays otherwise",
                f"a {lrf.kind} bundle with {lrf.config.data.n_points} points and min_support "
                f"{lrf.min_support}")
        key = id(lrf)
        if key not in self._framed:                   # the bundle is kept: its id stays its own
            describe, orient = self.spec.describe, lrf.spec.orient
            size = min(filter(None, (self.spec.infer_slice, lrf.spec.infer_slice)),
                       default=None)
            self._framed[key] = (lrf, jax.jit(in_slices(lambda p: describe(
                self.model, self.variables, p, orient(lrf.model, lrf.variables, p)), size)))
        return self._framed[key][1]

    def _whitening(self, whiten, framed: bool):
        """The :class:`~sphere_jax.bundles.whitening.Whitening` ``whiten`` names, or None."""
        if whiten is None or whiten is False:
            return None
        checks.choice(whiten, "whiten", ("auto",) + whitening_lib.SOURCES)
        if whiten == "auto":
            return None if framed else self.whitenings.get("default")
        if whiten not in self.whitenings:
            raise checks.InputError("whiten", f"None, 'auto' or a whitening this {self.kind} "
                                    f"bundle has ({', '.join(self.whitenings) or 'none'})",
                                    repr(whiten))
        return self.whitenings[whiten]

    # ---- jitted pieces ----------------------------------------------------------------------

    def __post_init__(self):
        self._framed, self._modes_fns = {}, {}
        spec = self.spec
        if spec.orient is not None:
            self._orient_fn = jax.jit(in_slices(
                lambda p: spec.orient(self.model, self.variables, p), spec.infer_slice))
        if spec.describe is not None and spec.describe_frames:
            def describe(p, frames=None):
                frames = FLARE_BATCH(p) if frames is None else frames
                return spec.describe(self.model, self.variables, p, frames)
            self._describe_fn = jax.jit(in_slices(describe, spec.infer_slice))
        elif spec.describe is not None:
            self._describe_fn = jax.jit(in_slices(
                lambda p: spec.describe(self.model, self.variables, p, None), spec.infer_slice))


ON_INVALID = ("raise", "mask")


def open3d_feature(desc_KxD):
    """Descriptors as the ``open3d.pipelines.registration.Feature`` that open3d's RANSAC and
    FGR take (:func:`sphere_jax.data.o3d_convert.feature`)."""
    return o3d_convert.feature(desc_KxD)


def bundle_path(name_or_path) -> str:
    """A bundle folder, or the shipped bundle of a model kind (``'lead'``, ``'compass'``,
    ``'lead_pn'``, ``'sound'``, ``'compass_shapes'``; :data:`sphere_jax.models.shipped.SHIPPED`)."""
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise checks.InputError("bundle", f"a bundle folder or one of {', '.join(shipped.SHIPPED)}",
                                checks.shown(name_or_path))
    name = os.fspath(name_or_path)
    if name in shipped.SHIPPED and not os.path.isdir(name):
        return shipped.bundle_path(name, required=True)
    if os.sep not in name and not os.path.exists(name):     # a word: meant as a kind
        raise checks.InputError("bundle", f"a bundle folder or one of {', '.join(shipped.SHIPPED)}",
                                f"{name!r}, which is neither")
    return name


def load_bundle(path) -> Bundle:
    """Load a bundle folder written at the end of training (:mod:`sphere_jax.bundle`), or a
    shipped one by model kind (:func:`bundle_path`)."""
    path = bundle_path(path)
    config = store.read_config(path)
    try:
        model = models.build(config)
    except Exception as e:                    # an unknown kind, a field the module lacks
        raise checks.BundleError(path, f"its config builds no model "
                                       f"({store.first_line(e)})") from None
    variables = store.read_variables(path)
    key = jax.random.PRNGKey(0)
    x = jax.ShapeDtypeStruct((1, config.data.n_points, 3), jnp.float32)
    expected = jax.eval_shape(functools.partial(model.init, train=False),
                              {"params": key, "dropout": key}, x)
    store.check_fits(path, variables, {k: expected.get(k, {}) for k in variables})
    return Bundle(model, variables, config, whitening_lib.load(path))


def cached_bundle(path) -> Bundle:
    """:func:`load_bundle`, once per bundle folder and process (the models compile once);
    a folder rewritten since (a new ``config.json``) is loaded again."""
    path = os.path.abspath(bundle_path(path))
    return _cached_bundle(path, store.stamp(path))


@functools.lru_cache(maxsize=16)
def _cached_bundle(path, _stamp):
    return load_bundle(path)


def shape_orienter(path):
    """:class:`ShapeOrienter` of the whole-shape Compass bundle at ``path``: what
    :func:`sphere_jax.training.train_and_evaluate` takes as ``orient_shapes`` for a config
    with ``orient_bundle``."""
    return ShapeOrienter(cached_bundle(path), store.fingerprint(bundle_path(path)))


@dataclasses.dataclass(frozen=True)
class ShapeOrienter:
    """The canonical frames a whole-shape Compass bundle gives whole shapes. ``key`` names the
    bundle's weights: caches of oriented shapes are keyed by it
    (:mod:`sphere_jax.data.oriented`)."""
    bundle: Bundle
    key: str

    def frames(self, shapes_BxNx3):
        """``(centres [B, 1, 3], frames [B, 3, 3])``: :func:`shape_frames`."""
        return shape_frames(self.bundle, shapes_BxNx3)


def shape_frames(bundle, shapes_BxNx3):
    """Compass's frame of each whole shape, ``(centres [B, 1, 3], frames [B, 3, 3])`` (columns
    x̂ ŷ ẑ in the shapes' coordinates). A shape with more points than the network reads
    (``config.data.n_points``) gives it an even subsample, the same points in any pose."""
    shapes_BxNx3 = np.asarray(shapes_BxNx3, np.float32)
    n, have = bundle.config.data.n_points, shapes_BxNx3.shape[1]
    pick = np.linspace(0, have, n, endpoint=False).astype(np.int64)
    unit, centres = patch_lib.unit_shapes(shapes_BxNx3)
    frames = np.asarray(bundle.orient_patches(unit[:, pick], chunk=min(len(unit), 256)))
    return centres, frames


def orient_shapes(bundle, shapes_BxNx3):
    """Shapes turned into the canonical frame a Compass bundle (trained on whole shapes)
    gives them: ``(p − centre) @ F``, in the shapes' own units."""
    centres, frames = shape_frames(bundle, shapes_BxNx3)
    return np.einsum("bnk,bkj->bnj", np.asarray(shapes_BxNx3, np.float32) - centres,
                     frames).astype(np.float32)
