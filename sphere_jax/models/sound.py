"""SOUND (thesis 4.2): LEAD and Compass in one network with a shared S2 layer — a
self-orienting descriptor.

The shared S2Conv feeds a descriptor branch (SO3Convs down to a one-channel map at bandwidth 4)
and an LRF branch (Compass's SO3Convs and soft-argmax). The decoder reconstructs the patch from
the descriptor; the LRF branch learns from the rotated copy as Compass does. The released
descriptor is the map rotated by the inverse of the patch's own LRF (:meth:`describe`), so it
no longer depends on the patch's orientation.
"""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax

from sphere_jax import fused, layers, soft_argmax
from sphere_jax.models.folding import FoldingDecoder
from sphere_jax.models.lead import canonical_descriptors
from sphere_jax.models.spherical import PatchSignal, SphericalStack


class Sound(nn.Module):
    """``__call__(patches, train) -> (rotations [N, 3, 3], descriptor maps [N, 8, 8, 8],
    reconstructions [N, M, 3])``."""
    s2_bandwidths: Sequence[int] = (24, 24)
    s2_features: int = 40
    descriptor_bandwidths: Sequence[int] = (24, 16, 12, 8, 4)
    descriptor_features: Sequence[int] = (40, 40, 40, 1)
    lrf_bandwidths: Sequence[int] = (24, 24, 24, 24)
    lrf_features: Sequence[int] = (20, 10, 1)
    n_shells: int = 4
    decoder_side: int = 35
    decoder_hidden: Sequence[int] = (514, 257, 128)
    temperature: float = 1.0
    window: float | None = None
    fused: bool = True          # inference path of sphere_jax.fused (same outputs, faster)

    def setup(self):
        self.signal = PatchSignal(self.s2_bandwidths[0], self.n_shells)
        self.s2 = layers.S2Conv(self.s2_features, *self.s2_bandwidths)
        self.s2_norm = layers.GridBatchNorm()
        # No ReLU after the descriptor layer: it stays band-limited, so rotating it by its LRF
        # (spectrally) is exact (see models/lead.py).
        self.descriptor = SphericalStack(self.descriptor_features, self.descriptor_bandwidths,
                                         s2_first=False, final_relu=False,
                                         fused=self.fused)
        self.lrf = SphericalStack(self.lrf_features, self.lrf_bandwidths, s2_first=False,
                                  final_relu=False, fused=self.fused)
        self.decoder = FoldingDecoder(self.decoder_side, self.decoder_hidden)

    def trunk(self, patches, train):
        """The shared S2 layer's output: grids ``[N, C, 2B, 2B, 2B]``, or at inference with
        ``fused`` their spectrum (:mod:`sphere_jax.fused`) — at B = 24 the grids of a chunk of
        256 patches would take 4.5 GB."""
        x = self.signal(patches)
        if train or not self.fused:
            return nn.relu(self.s2_norm(self.s2(x), train))
        lmax = max(self.descriptor_bandwidths[1], self.lrf_bandwidths[1])
        h = self.s2(fused.analyse(x, self.s2_bandwidths[1], on_so3=False))
        scale, shift = layers.batch_norm_affine(self.s2_norm, self.s2_features)
        return fused.pointwise(h, scale, shift, lmax)

    def __call__(self, patches, train: bool = False):
        h = self.trunk(patches, train)
        maps = self.descriptor(h, train)[:, 0]
        lrf_maps = self.lrf(h, train)[:, 0]
        rot = jax.vmap(lambda m: soft_argmax.soft_argmax_rotation(
            m, self.temperature, self.window))(lrf_maps)
        return rot, maps, self.decoder(maps.reshape(maps.shape[0], -1), train)

    def describe(self, patches):
        """Self-oriented descriptors ``[N, 512]``: each map rotated by its LRF's inverse."""
        rot, maps, _ = self(patches, train=False)
        return canonical_descriptors(maps, rot)
