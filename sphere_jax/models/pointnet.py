"""PointNet without T-nets: a shared per-point MLP and a max pool. The encoder of LEAD-PN (on
LRF-oriented patches) and of the rotated-classification experiment (:mod:`.classify`)."""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

BN_EPSILON = 1e-5       # flax's default, named so that the folded inference path uses the same
# Patches per step of the inference loop: one patch's activations (1024 points × 512 floats:
# 2 MB) stay in a core's cache; more per step was slower on the 2-core development machine.
PATCHES_PER_STEP = 1


class PointNetEncoder(nn.Module):
    """``points [..., P, 3] -> code [..., features[-1]]``."""
    features: Sequence[int] = (64, 128, 512)
    axis_name: str | None = None    # data-parallel batch axis of the batch norms

    @nn.compact
    def __call__(self, points, train: bool):
        if not train and not self.is_initializing():
            return inference_codes(self.variables, points, len(self.features))
        x = points
        for width in self.features:
            x = nn.relu(nn.BatchNorm(use_running_average=not train, epsilon=BN_EPSILON,
                                     axis_name=self.axis_name)(nn.Dense(width)(x)))
        return jnp.max(x, axis=-2)


def folded_layers(variables, n_layers: int):
    """``[(kernel [C_in, C_out], bias [C_out])]``: each Dense with the inference batch norm
    after it folded in (``BatchNorm(Dense(x)) = x · kernel + bias``)."""
    if "batch_stats" not in variables:
        raise ValueError("PointNetEncoder at inference needs the 'batch_stats' collection (its "
                         f"batch norms' running moments); got only {sorted(variables)}")
    params, stats = variables["params"], variables["batch_stats"]
    layers = []
    for i in range(n_layers):
        dense, norm, moments = params[f"Dense_{i}"], params[f"BatchNorm_{i}"], \
            stats[f"BatchNorm_{i}"]
        scale = norm["scale"] * jax.lax.rsqrt(moments["var"] + BN_EPSILON)
        layers.append((dense["kernel"] * scale,
                       (dense["bias"] - moments["mean"]) * scale + norm["bias"]))
    return layers


def inference_codes(variables, points, n_layers: int):
    """The encoder at inference, ``points [..., P, 3] -> [..., C]``, one patch at a time.

    Same codes as the layer-by-layer pass to float32 round-off, 3× faster on a CPU: a chunk of
    256 patches of 1024 points carries 0.5 GB of 512-wide activations through memory, one
    patch 2 MB that stay in the cache. The max pool commutes with the last bias and ReLU, so
    the last layer's activations are reduced straight after its GEMM."""
    layers = folded_layers(variables, n_layers)
    *last_hidden, (kernel, bias) = layers

    def one_patch(p_Px3):
        h = p_Px3
        for k, b in last_hidden:
            h = jax.nn.relu(h @ k + b)
        return jax.nn.relu(jnp.max(h @ kernel, axis=0) + bias)

    flat = points.reshape((-1,) + points.shape[-2:])
    codes = jax.lax.map(one_patch, flat, batch_size=PATCHES_PER_STEP)
    return codes.reshape(points.shape[:-2] + codes.shape[-1:])
