"""The spherical CNN trunk shared by the models: patch -> signal -> S2Conv -> SO3Conv ...."""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn

from sphere_jax import layers, signal


class PatchSignal(nn.Module):
    """Unit-ball patches ``[N, P, 3]`` -> spherical signals ``[N, K, 2B, 2B]`` (no parameters)."""
    bandwidth: int
    n_shells: int = 4

    def __call__(self, patches):
        return signal.patch_signals(patches, 1.0, self.bandwidth, self.n_shells)


class SphericalStack(nn.Module):
    """Convolutions with batch norm between: ``features[i]`` channels from bandwidth
    ``bandwidths[i]`` to ``bandwidths[i + 1]``. The first layer is an S2Conv when ``s2_first``;
    ReLU after every layer but the last unless ``final_relu``."""
    features: Sequence[int]
    bandwidths: Sequence[int]
    s2_first: bool = True
    final_relu: bool = True
    grid: str = "near_identity"

    @nn.compact
    def __call__(self, x, train: bool):
        if len(self.bandwidths) != len(self.features) + 1:
            raise ValueError(f"bandwidths must have one entry more than features, got "
                             f"{self.bandwidths} and {self.features}")
        last = len(self.features) - 1
        for i, f in enumerate(self.features):
            conv = layers.S2Conv if (i == 0 and self.s2_first) else layers.SO3Conv
            x = conv(f, self.bandwidths[i], self.bandwidths[i + 1], self.grid)(x)
            x = layers.GridBatchNorm()(x, train)
            if i < last or self.final_relu:
                x = nn.relu(x)
        return x
