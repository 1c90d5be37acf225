"""LEAD under Compass's frame hypotheses (``lead@compass+modes``).

A Compass frame is right or wrong whole: on a symmetric support its SO(3) map holds the right
frame as a lesser mode as often as the strongest. Here each keypoint keeps the :data:`MODES`
strongest modes (:meth:`~sphere_jax.bundles.inference.Bundle.orient_modes`) and LEAD describes
it under each — one pass of the network; each frame is a spectral turn of the same SO(3) map —
as descriptors ``[K, H, D]``, which :func:`~sphere_jax.registration.matching.mutual_matches`
matches by the smallest distance over the H × H hypothesis pairs.
"""
from __future__ import annotations

import jax
import numpy as np

from sphere_jax import parallel
from sphere_jax.bundles import inference
from sphere_jax.models import lead as lead_model

# Hypotheses per keypoint, chosen on the validation pairs (7-scenes-stairs, shelf-bin;
# docs/training.md): 3 matched as well as 4 at 9/16 of the matching work.
MODES = 3


def turned(maps_KxD, frames_KxHx3x3, chunk=None):
    """LEAD's SO(3) maps (described in the scan's axes: identity frames) turned into each of
    ``H`` frames per keypoint: ``[K, H, D]``."""
    k, h = frames_KxHx3x3.shape[:2]
    if not k:
        return np.zeros((0, h, maps_KxD.shape[1]), np.float32)
    side = round(maps_KxD.shape[1] ** (1 / 3))
    cubes = np.repeat(maps_KxD.reshape(k, side, side, side), h, axis=0)
    frames = np.ascontiguousarray(frames_KxHx3x3.reshape(k * h, 3, 3), np.float32)
    out = parallel.stream_chunked(_TURN, lambda a, b: (cubes[a:b], frames[a:b]), k * h, chunk)
    return np.asarray(out).reshape(k, h, -1)


_TURN = jax.jit(lead_model.canonical_descriptors)


def lead_modes(radius, bundles, chunk=None, k=MODES, **_):
    """The builder of ``lead@compass+modes``: ``describe_all([fragment, ...]) ->
    [[K, k, D], ...]``, whitened by LEAD's ``compass`` whitening where it has one; NaN where a
    keypoint has too few support points."""
    lead = inference.cached_bundle(bundles["lead"])
    compass = inference.cached_bundle(bundles["compass"])
    white = lead.whitenings.get("compass")

    def describe_all(fs):
        clouds = [(f.points, f.keypoints) for f in fs]
        modes = compass.orient_modes_clouds(clouds, k, radius=radius, chunk=chunk,
                                            on_invalid="mask")
        eye = [np.broadcast_to(np.eye(3, dtype=np.float32), (len(kp), 3, 3))
               for _, kp in clouds]
        maps = lead.describe_clouds(clouds, radius=radius, chunk=chunk, frames=eye,
                                    on_invalid="mask", whiten=None)
        out = []
        for (frames, oriented), (m, described) in zip(modes, maps):
            ok = oriented & described
            d = np.full((len(ok), k, m.shape[1]), np.nan, np.float32)
            t = turned(m[ok], frames[ok], chunk)
            d[ok] = t if white is None else white.apply(t.reshape(-1, t.shape[-1])).reshape(
                t.shape)
            out.append(d)
        return out
    return describe_all
