"""PointNet without T-nets: a shared per-point MLP and a max pool. The encoder of LEAD-PN (on
LRF-oriented patches) and of the rotated-classification experiment (:mod:`.classify`)."""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax.numpy as jnp


class PointNetEncoder(nn.Module):
    """``points [N, P, 3] -> code [N, features[-1]]``."""
    features: Sequence[int] = (64, 128, 512)
    axis_name: str | None = None    # data-parallel batch axis of the batch norms

    @nn.compact
    def __call__(self, points, train: bool):
        x = points
        for width in self.features:
            x = nn.relu(nn.BatchNorm(use_running_average=not train,
                                              axis_name=self.axis_name)(nn.Dense(width)(x)))
        return jnp.max(x, axis=-2)
