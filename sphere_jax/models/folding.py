"""AtlasNet-style folding decoder: a fixed 2-D grid, concatenated with the code, folded into
3-D by a per-point MLP (batch norm + ReLU after the first three layers, tanh last).

The first layer of the MLP sees ``[grid point, code]``; its product splits into the grid's part
(one ``[G, width]`` table) plus the code's part (one row per patch), so the code is multiplied
once per patch instead of once per grid point — the same map with ~60 % fewer FLOPs.
"""
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


class _GridCodeDense(nn.Module):
    """``Dense(width)`` of ``concat([grid [G, 2], code [N, D]])`` -> ``[N, G, width]``, with the
    parameters (``kernel [2 + D, width]``, ``bias``) and initialisation of ``nn.Dense``."""
    width: int

    @nn.compact
    def __call__(self, grid_Gx2, code_NxD):
        kernel = self.param("kernel", nn.initializers.lecun_normal(),
                            (grid_Gx2.shape[-1] + code_NxD.shape[-1], self.width))
        bias = self.param("bias", nn.initializers.zeros_init(), (self.width,))
        g = grid_Gx2.shape[-1]
        # The grid's part is the same for every patch. Broadcast, its gradient was a reduction
        # over the patches that XLA's CPU backend ran at a fifth of the speed of this outer
        # product's, a GEMV (32 patches x 1024 x 512: 184 -> 45 ms for the layer's gradient).
        ones = jnp.ones(code_NxD.shape[:1], code_NxD.dtype)
        return jnp.einsum("n,gw->ngw", ones, grid_Gx2 @ kernel[:g]) \
            + (code_NxD @ kernel[g:] + bias)[:, None, :]


class FoldingDecoder(nn.Module):
    """``code [N, D] -> points [N, n_side², 3]`` in [-1, 1]³."""
    n_side: int = 35
    hidden: Sequence[int] = (514, 257, 128)
    axis_name: str | None = None    # data-parallel batch axis of the batch norms

    @nn.compact
    def __call__(self, code, train: bool):
        grid = jnp.asarray(unit_grid(self.n_side))
        x = None
        for k, width in enumerate(self.hidden):
            x = (_GridCodeDense(width, name="Dense_0")(grid, code) if k == 0
                 else nn.Dense(width, name=f"Dense_{k}")(x))
            x = nn.relu(nn.BatchNorm(use_running_average=not train,
                                     axis_name=self.axis_name, name=f"BatchNorm_{k}")(x))
        return jnp.tanh(nn.Dense(3, name=f"Dense_{len(self.hidden)}")(x))
