"""AtlasNet-style folding decoder: a fixed 2-D grid, concatenated with the code, folded into
3-D by a per-point MLP (batch norm + ReLU after the first three layers, tanh last)."""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax.numpy as jnp
import numpy as np


def unit_grid(n_side: int):
    """``[n_side², 2]`` points on a regular grid of [0, 1]²."""
    t = np.linspace(0.0, 1.0, n_side)
    u, v = np.meshgrid(t, t, indexing="ij")
    return np.stack([u.ravel(), v.ravel()], 1).astype(np.float32)


class FoldingDecoder(nn.Module):
    """``code [N, D] -> points [N, n_side², 3]`` in [-1, 1]³."""
    n_side: int = 35
    hidden: Sequence[int] = (514, 257, 128)
    axis_name: str | None = None    # data-parallel batch axis of the batch norms

    @nn.compact
    def __call__(self, code, train: bool):
        grid = jnp.asarray(unit_grid(self.n_side))
        n = code.shape[0]
        x = jnp.concatenate([jnp.broadcast_to(grid, (n,) + grid.shape),
                             jnp.broadcast_to(code[:, None, :], (n, grid.shape[0],
                                                                 code.shape[-1]))], -1)
        for width in self.hidden:
            x = nn.relu(nn.BatchNorm(use_running_average=not train,
                                              axis_name=self.axis_name)(nn.Dense(width)(x)))
        return jnp.tanh(nn.Dense(3)(x))
