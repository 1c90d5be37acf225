"""SOUND (thesis 4.2): LEAD and Compass in one network with a shared S2 layer — a
self-orienting descriptor.

The shared S2Conv feeds a descriptor branch (SO3Convs down to a one-channel map at bandwidth 4)
and an LRF branch (Compass's SO3Convs and soft-argmax). The decoder reconstructs the patch from
the descriptor; the LRF branch learns from the rotated copy as Compass does. The released
descriptor is the map rotated by the inverse of the patch's own LRF (:meth:`describe`), so it
no longer depends on the patch's orientation.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import flax.linen as nn
import jax

from sphere_jax.models import compass, lead
from sphere_jax.models.folding import FoldingDecoder
from sphere_jax.models.lead import canonical_descriptors
from sphere_jax.models.spec import ModelSpec
from sphere_jax.models.spherical import PatchSignal, SphericalStack
from sphere_jax.spherical import fused, layers, soft_argmax


class SoundOut(NamedTuple):
    rotations: jax.Array        # [N, 3, 3] from the LRF branch
    maps: jax.Array             # [N, 8, 8, 8] descriptor maps (not yet oriented)
    reconstructions: jax.Array  # [N, M, 3]


class Sound(nn.Module):
    """``__call__(patches [N, P, 3], train) -> SoundOut``."""
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
    fused: bool = True          # spectral-domain path (sphere_jax.spherical.fused)
    axis_name: str | None = None    # data-parallel batch axis (layers.GridBatchNorm)

    def setup(self):
        self.signal = PatchSignal(self.s2_bandwidths[0], self.n_shells)
        self.s2 = layers.S2Conv(self.s2_features, *self.s2_bandwidths)
        self.s2_norm = layers.GridBatchNorm(axis_name=self.axis_name)
        # No ReLU after the descriptor layer: it stays band-limited, so rotating it by its LRF
        # (spectrally) is exact (see models/lead.py).
        self.descriptor = SphericalStack(self.descriptor_features, self.descriptor_bandwidths,
                                         s2_first=False, final_relu=False,
                                         fused=self.fused, axis_name=self.axis_name)
        self.lrf = SphericalStack(self.lrf_features, self.lrf_bandwidths, s2_first=False,
                                  final_relu=False, fused=self.fused, axis_name=self.axis_name)
        self.decoder = FoldingDecoder(self.decoder_side, self.decoder_hidden,
                                      axis_name=self.axis_name)

    def trunk(self, patches, train):
        """The shared S2 layer's output: grids ``[N, C, 2B, 2B, 2B]``, or with ``fused`` their
        spectrum (:mod:`~sphere_jax.spherical.fused`) — at B = 24 the grids of a chunk of 256
        patches would take 4.5 GB."""
        x = self.signal(patches)
        if not self.fused:
            return nn.relu(self.s2_norm(self.s2(x), train))
        lmax = max(self.descriptor_bandwidths[1], self.lrf_bandwidths[1])
        h = self.s2(fused.analyse(x, self.s2_bandwidths[1], on_so3=False))
        scale, shift = self.s2_norm(h, train)
        return fused.pointwise(h, scale, shift, lmax)

    def __call__(self, patches, train: bool = False):
        h = self.trunk(patches, train)
        maps = self.descriptor(h, train)[:, 0]
        lrf_maps = self.lrf(h, train)[:, 0]
        rot = jax.vmap(lambda m: soft_argmax.soft_argmax_rotation(
            m, self.temperature, self.window))(lrf_maps)
        return SoundOut(rot, maps, self.decoder(maps.reshape(maps.shape[0], -1), train))

    def describe(self, patches):
        """Self-oriented descriptors ``[N, 512]``: each map rotated by its LRF's inverse."""
        out = self(patches, train=False)
        return canonical_descriptors(out.maps, out.rotations)


def loss(out: SoundOut, batch, config):
    """``chamfer_weight · Chamfer + angular_weight · angular`` (seed 4.2: 100 and 1); the
    reconstructions of the originals only (the first half of the batch)."""
    b = batch["patches"].shape[0]
    angular = compass.angular_loss(out.rotations, batch)
    chamfer = lead.reconstruction_loss(out.reconstructions[:b], {"inputs": batch["patches"]})
    total = config.loss.chamfer_weight * chamfer + config.loss.angular_weight * angular
    return total, {"angular": angular, "chamfer": chamfer}


def describe(model, variables, patches, frames=None):
    return model.apply(variables, patches, method="describe")


SPEC = ModelSpec(kind="sound", module=Sound, outputs=SoundOut, loss=loss,
                 inputs=compass.with_copies, copies=True, orient=compass.orient,
                 describe=describe)
