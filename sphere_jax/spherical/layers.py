"""flax.linen layers: thin wrappers over :mod:`correlation` that own the kernel weights.

All layers are channels first (:mod:`so3`): S2 ``[N, C, 2B, 2B]``, SO(3) ``[N, C, 2B, 2B, 2B]``.
No bias: every convolution in our models is followed by batch norm, which has its own.
"""
from __future__ import annotations

import numpy as np
import flax.linen as nn
import jax.numpy as jnp

from sphere_jax.spherical import correlation, fused, transforms
from sphere_jax.spherical.correlation import KernelGrid


def _resolve_grid(grid, on_so3, b_in) -> KernelGrid:
    if isinstance(grid, KernelGrid):
        if grid.on_so3 != on_so3:
            raise ValueError(f"grid is an {'SO(3)' if grid.on_so3 else 'S2'} grid, this layer "
                             f"needs an {'SO(3)' if on_so3 else 'S2'} grid")
        return grid
    return correlation.make_grid(grid, on_so3, b_in)


def kernel_init(gain: float, fan_in: int):
    """Normal weights with variance gain²/fan_in, fan_in = grid points × input channels: the
    output at a rotation is a sum of fan_in weighted input values, so its variance is that of
    the input times gain² (gain √2 compensates the half of the power a ReLU removes)."""
    return nn.initializers.normal(stddev=gain / np.sqrt(fan_in))


class _SphericalConv(nn.Module):
    features: int
    b_in: int
    b_out: int
    grid: str | KernelGrid = "near_identity"
    gain: float = float(np.sqrt(2.0))

    on_so3 = False

    @nn.compact
    def __call__(self, x):
        """Grids in, grids out; or a :class:`fused.Spectrum` in (analysed to ``b_out``) and the
        output's spectrum out (the fused inference path of :mod:`fused`)."""
        spectral = isinstance(x, fused.Spectrum)
        kind = "SO(3)" if self.on_so3 else "S2"
        if spectral:
            if x.on_so3 != self.on_so3 or x.bandwidth != self.b_in:
                raise ValueError(f"{type(self).__name__} expects the spectrum of an {kind} grid "
                                 f"at b_in={self.b_in}, got {'SO(3)' if x.on_so3 else 'S2'} at "
                                 f"bandwidth {x.bandwidth}")
            c_in = x.channels
        else:
            grid_ndim = 3 if self.on_so3 else 2
            b = transforms.grid_bandwidth(x, grid_ndim)
            if b != self.b_in:
                raise ValueError(f"{type(self).__name__} expects b_in={self.b_in} (grid axes of "
                                 f"size {2 * self.b_in}), got input of shape {tuple(x.shape)} "
                                 f"(bandwidth {b})")
            c_in = x.shape[-grid_ndim - 1]
        grid = _resolve_grid(self.grid, self.on_so3, self.b_in)
        w = self.param("kernel", kernel_init(self.gain, grid.size * c_in),
                       grid.shape + (c_in, self.features))
        if spectral:
            return fused.correlate(x, w, grid, self.b_out)
        fn = correlation.so3_correlate if self.on_so3 else correlation.s2_correlate
        return fn(x, w, grid, self.b_out)


class S2Conv(_SphericalConv):
    """S2 ``[N, C, 2B_in, 2B_in]`` -> SO(3) ``[N, features, 2B_out, 2B_out, 2B_out]``."""
    on_so3 = False


class SO3Conv(_SphericalConv):
    """SO(3) ``[N, C, 2B_in, 2B_in, 2B_in]`` -> SO(3) ``[N, features, 2B_out, 2B_out, 2B_out]``."""
    on_so3 = True


class GridBatchNorm(nn.Module):
    """Batch norm per channel, statistics over the batch and every grid cell (channels first).

    Per-channel affine maps commute with rotations, so the layer keeps equivariance up to the
    statistics, which are themselves (nearly) rotation invariant.
    """
    momentum: float = 0.9
    epsilon: float = 1e-5
    use_scale: bool = True

    @nn.compact
    def __call__(self, x, train: bool):
        return nn.BatchNorm(use_running_average=not train, axis=1, momentum=self.momentum,
                            epsilon=self.epsilon, use_scale=self.use_scale)(x)


def batch_norm_affine(norm: GridBatchNorm, channels: int):
    """``(scale [C], shift [C])`` of an inference-mode :class:`GridBatchNorm`, which is affine:
    read off by applying it to 0 and to 1."""
    out = norm(jnp.stack([jnp.zeros(channels), jnp.ones(channels)]), train=False)
    return out[1] - out[0], out[0]


def haar_pool(x):
    """Rotation-invariant pooling ``[N, C, 2B, 2B, 2B] -> [N, C]`` (Haar mean)."""
    return transforms.so3_haar_mean(x)
