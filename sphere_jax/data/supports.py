"""The supports of keypoints as the networks see them: every keypoint's neighbours within a
radius, resampled evenly to a fixed count (:data:`DRAW`) in units of the radius, drawn chunk by
chunk so memory stays that of one chunk whatever the number of keypoints."""
from __future__ import annotations

import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax import checks
from sphere_jax.data import patches as patch_lib

# How every network's support is drawn when it describes or orients (patches.DRAWS); an
# evaluation's kept results carry it (eval/resume.py), so a change redoes them.
DRAW = "even"

# Fewest support points a keypoint needs: below it the N points of a patch are drawn from a
# handful (one neighbour gave N copies of one point) and no frame or descriptor means anything.
MIN_SUPPORT = 16


class SupportStream:
    """The supports of ``K`` keypoints (indices into ``points`` or coordinates, which are
    queried, not added to the cloud), counted at once and drawn chunk by chunk: memory is that
    of one chunk's neighbour lists, whatever K. Only the keypoints with at least
    ``min_support`` points (the centre excluded) are drawn: ``rows`` of them, ``n`` in all.
    :meth:`make` must be called on consecutive row ranges in order (the patch sampling is one
    random stream, so the chunking does not change the patches)."""

    def __init__(self, points, keypoints, radius, n_points, seed, min_support, draw=DRAW):
        seed = checks.non_negative(seed, "seed", integer=True)
        self.points = checks.cloud(points)
        idx, coords = checks.keypoints(keypoints, len(self.points))
        self.centres = self.points[idx] if coords is None else coords
        self.radius, self.n_points, self.min_support = radius, n_points, min_support
        self.draw = checks.choice(draw, "draw", patch_lib.DRAWS)
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
                                       self.n_points, self._rng, 1, self.tree, self.draw)
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


def extract_unit_patches(points, keypoints, radius, n_points, seed=0, min_support=1,
                         draw=DRAW):
    """All patches ``[K, n_points, 3]`` at once, in units of ``radius``, around ``keypoints``
    (indices ``[K]`` or coordinates ``[K, 3]``); every keypoint must have ``min_support``
    support points."""
    stream = SupportStream(points, keypoints, checks.positive(radius, "radius"),
                           checks.positive(n_points, "n_points", integer=True), seed,
                           min_support, draw)
    stream.check("raise")
    return stream.make(0, stream.n)[0]


class StreamChain:
    """Several :class:`SupportStream` (one per cloud) as one range of ``n`` rows, so that one
    chunked run goes from one cloud to the next without draining (no core idles at a cloud's
    last chunk). Each stream still draws its own rows in order: the patches are those of
    separate runs."""

    def __init__(self, streams):
        self.streams = list(streams)
        self.ends = np.cumsum([s.n for s in self.streams], dtype=np.int64)
        self.n = int(self.ends[-1]) if len(self.ends) else 0

    def make(self, start, stop):
        """Inputs of chained rows ``start:stop`` (:meth:`SupportStream.make`)."""
        parts, begin = [], 0
        for stream, end in zip(self.streams, self.ends):
            a, b = max(start, begin), min(stop, int(end))
            if a < b:
                parts.append(stream.make(a - begin, b - begin))
            begin = int(end)
        return tuple(np.concatenate(p) for p in zip(*parts))

    def split(self, values):
        """Computed rows ``[n, ...]`` as one array per stream."""
        return np.split(np.asarray(values), self.ends[:-1]) if self.n else \
            [np.asarray(values)] * len(self.streams)
