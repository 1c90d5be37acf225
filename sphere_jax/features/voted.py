"""The pair vote's two descriptors: ``lead_vote`` (LEAD matched once in Compass's frames, then
turned spectrally into the voted frame) and ``shot_vote`` (SHOT in its LRF, binned again in the
voted frame). Each builds ``(first, again)`` of :class:`~sphere_jax.registration.vote.VotedFrames`
(the vote itself) from ``(radius, bundles, chunk, whiten)``."""
from __future__ import annotations

import numpy as np

from sphere_jax.bundles import inference, whitening
from sphere_jax.features import builders, descriptors, lrfs, modes


def shot_vote(radius, bundles=None, chunk=None, whiten=True):
    def first(f):
        nb = builders.neighbourhoods(f, f.keypoints, radius)
        frames = lrfs.shot_lrf(nb)
        return descriptors.shot(nb, f.normals, frames), frames, None

    last = {}

    def again(f, _, rotation_3x3):
        # Only the last scan's supports are kept (its candidate frames come one after
        # another): a scene's scans would hold them all.
        if last.get("scan") is not f:
            last.update(scan=f, nb=builders.neighbourhoods(f, f.keypoints, radius))
        nb = last["nb"]
        return descriptors.shot(nb, f.normals, builders.one_frame(rotation_3x3,
                                                                     len(f.keypoints)))
    return first, again


def lead_vote(radius, bundles, chunk=None, whiten=True):
    lead = inference.cached_bundle(bundles["lead"])
    compass = inference.cached_bundle(bundles["compass"])
    # The first pass matches in Compass's frames (their whitening); the second in one frame
    # per scan, where no map is in a canonical pose: the rotation average of the statistics.
    first_white = lead.whitenings.get("compass") if whiten else None
    fitted = lead.whitenings.get("default", first_white) if whiten else None
    shared_white = None if fitted is None else whitening.rotation_averaged(
        fitted, lead.config.model_kwargs["bandwidths"][-1])

    def white(w, desc_KxD):
        return desc_KxD if w is None or not len(desc_KxD) else w.apply(desc_KxD)

    def turned(maps_KxD, frames_Kx3x3):
        return modes.turned(maps_KxD, frames_Kx3x3[:, None], chunk)[:, 0]

    def first(f):
        k = len(f.keypoints)
        # LEAD's SO(3) maps in the scan's own axes, computed once: every frame after this is
        # a spectral turn of them, not another pass of the network.
        # An undescribed keypoint's map is a NaN row: every turn keeps it one (each map is
        # turned on its own), and it never matches.
        maps, valid = lead.describe(f.points, f.keypoints, radius=radius, chunk=chunk,
                                    frames=builders.one_frame(np.eye(3), k),
                                    on_invalid="mask")
        maps = builders.masked((maps, valid), np.nan)
        frames, oriented = compass.orient(f.points, f.keypoints, radius=radius, chunk=chunk,
                                          on_invalid="mask")
        frames = builders.masked((frames, oriented), np.eye(3))
        desc = turned(maps, frames) if k else maps
        frames[~(valid & oriented)] = np.nan          # no proposal from an undescribed keypoint
        return white(first_white, desc), frames, maps

    def again(f, maps, rotation_3x3):
        if len(maps) and not np.allclose(rotation_3x3, np.eye(3)):
            maps = turned(maps, builders.one_frame(rotation_3x3, len(maps)))
        return white(shared_white, maps)
    return first, again
