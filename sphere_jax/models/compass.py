"""Compass (thesis 3.1): a learned local reference frame.

Patch -> spherical signal -> S2Conv + SO3Convs -> one SO(3) map -> Parzen soft-argmax ->
rotation F. Equivariance of the network makes ``F(R·P) ≈ R·F(P)``; the training signal is the
geodesic distance between the two sides, on a rotated and occluded copy of the patch.
"""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax

from sphere_jax import soft_argmax
from sphere_jax.models.spherical import PatchSignal, SphericalStack


class Compass(nn.Module):
    """``__call__(patches [N, P, 3], train) -> (rotations [N, 3, 3], maps [N, 2B, 2B, 2B])``;
    the columns of each rotation are the LRF axes."""
    bandwidths: Sequence[int] = (24, 24, 24, 24, 24)
    features: Sequence[int] = (40, 20, 10, 1)
    n_shells: int = 4
    temperature: float = 1.0
    window: float | None = None
    fused: bool = True          # inference path of sphere_jax.fused (same outputs, faster)

    @nn.compact
    def __call__(self, patches, train: bool = False):
        x = PatchSignal(self.bandwidths[0], self.n_shells)(patches)
        maps = SphericalStack(self.features, self.bandwidths, final_relu=False,
                              fused=self.fused)(x, train)[:, 0]
        rot = jax.vmap(lambda m: soft_argmax.soft_argmax_rotation(
            m, self.temperature, self.window))(maps)
        return rot, maps
