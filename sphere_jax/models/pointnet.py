"""PointNet without T-nets: a shared per-point MLP and a max pool (encoder), plus a classifier
head. Used by LEAD-PN (on LRF-oriented patches) and the rotated-classification experiment."""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax.numpy as jnp


class PointNetEncoder(nn.Module):
    """``points [N, P, 3] -> code [N, features[-1]]``."""
    features: Sequence[int] = (64, 128, 512)

    @nn.compact
    def __call__(self, points, train: bool):
        x = points
        for width in self.features:
            x = nn.relu(nn.BatchNorm(use_running_average=not train)(nn.Dense(width)(x)))
        return jnp.max(x, axis=-2)


class PointNetClassifier(nn.Module):
    """``points [N, P, 3] -> logits [N, n_classes]``."""
    n_classes: int
    features: Sequence[int] = (64, 64, 64, 128, 1024)
    head: Sequence[int] = (512, 256)
    dropout: float = 0.3

    @nn.compact
    def __call__(self, points, train: bool = False):
        x = PointNetEncoder(self.features)(points, train)
        for width in self.head:
            x = nn.relu(nn.BatchNorm(use_running_average=not train)(nn.Dense(width)(x)))
            x = nn.Dropout(self.dropout, deterministic=not train)(x)
        return nn.Dense(self.n_classes)(x)
