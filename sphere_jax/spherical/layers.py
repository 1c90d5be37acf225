"""flax.linen layers: thin wrappers over :mod:`correlation` that own the kernel weights.

All layers are channels first (:mod:`so3`): S2 ``[N, C, 2B, 2B]``, SO(3) ``[N, C, 2B, 2B, 2B]``.
No bias: every convolution in our models is followed by batch norm, which has its own.
"""
from __future__ import annotations

import numpy as np
import flax.linen as nn
import jax
import jax.numpy as jnp

from sphere_jax import checks
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
        checks.positive(self.features, f"{type(self).__name__}.features", integer=True)
        if spectral:
            if x.on_so3 != self.on_so3 or x.bandwidth != self.b_in:
                raise ValueError(f"{type(self).__name__} expects the spectrum of an {kind} grid "
                                 f"at b_in={self.b_in}, got {'SO(3)' if x.on_so3 else 'S2'} at "
                                 f"bandwidth {x.bandwidth}")
            c_in = x.channels
        else:
            grid_ndim = 3 if self.on_so3 else 2
            if x.ndim != grid_ndim + 2:
                # An SO(3) grid [N, C, 2B, 2B, 2B] would otherwise pass as S2 grids of a batch
                # [N, C] with 2B channels: the rank is what tells them apart.
                form = ", ".join(["2B"] * grid_ndim)
                raise checks.InputError(f"the input of {type(self).__name__}",
                                        f"an {kind} grid [N, C, {form}]",
                                        f"shape {tuple(x.shape)}")
            b = transforms.grid_bandwidth(x, grid_ndim)
            if b != self.b_in:
                raise ValueError(f"{type(self).__name__} expects b_in={self.b_in} (grid axes of "
                                 f"size {2 * self.b_in}), got input of shape {tuple(x.shape)} "
                                 f"(bandwidth {b})")
            c_in = x.shape[-grid_ndim - 1]
        grid = _resolve_grid(self.grid, self.on_so3, self.b_in)
        if self.has_variable("params", "kernel"):        # applied with trained parameters
            have = self.get_variable("params", "kernel").shape
            if have[-2] != c_in or have[-1] != self.features:
                raise checks.InputError(f"the input of {type(self).__name__}",
                                        f"{have[-2]} channels (its parameters map {have[-2]} "
                                        f"to {have[-1]})", f"{c_in} channels")
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


class _HaarStatistics(nn.Module):
    """The variables of one batch norm (``scale``, ``bias``; running ``mean``, ``var``) and the
    affine map they define, from per-signal Haar moments ``[N, C]`` (train) or the running
    statistics (inference)."""
    momentum: float
    epsilon: float
    use_scale: bool
    axis_name: str | None

    @nn.compact
    def __call__(self, moments, channels: int, train: bool):
        ra_mean = self.variable("batch_stats", "mean", jnp.zeros, (channels,), jnp.float32)
        ra_var = self.variable("batch_stats", "var", jnp.ones, (channels,), jnp.float32)
        if train:
            mean, mean_sq = (jnp.mean(m, 0) for m in moments)
            if self.axis_name is not None:         # data-parallel: the global batch's moments
                mean, mean_sq = jax.lax.pmean((mean, mean_sq), self.axis_name)
            var = jnp.maximum(mean_sq - jnp.square(mean), 0.0)
            if not self.is_initializing():
                ra_mean.value = self.momentum * ra_mean.value + (1 - self.momentum) * mean
                ra_var.value = self.momentum * ra_var.value + (1 - self.momentum) * var
        else:
            mean, var = ra_mean.value, ra_var.value
        scale = jax.lax.rsqrt(var + self.epsilon)
        if self.use_scale:
            scale = scale * self.param("scale", nn.initializers.ones, (channels,), jnp.float32)
        shift = self.param("bias", nn.initializers.zeros, (channels,), jnp.float32) - mean * scale
        return scale, shift


class GridBatchNorm(nn.Module):
    """Batch norm per channel of SO(3) signals with Haar-weighted statistics.

    The batch mean and variance of channel c are taken over the batch and over SO(3) with the
    Haar measure: ``E[x] = mean_n ∫ x_nc dR``, ``E[x²] = mean_n ∫ x_nc² dR``. For band-limited
    signals both are exact on the grid (SOFT quadrature) and in the spectrum (degree-0
    coefficient; Parseval), so the layer-by-layer path (grids) and the fused path (spectra)
    compute the same statistics without the fused one ever forming a grid. This deliberately
    departs from s2cnn, whose unweighted mean over the grid cells over-weights the cells near
    the poles (the SOFT grid is dense in α, γ there) and so changes when the signal rotates;
    the Haar statistics of a rotated band-limited signal are the same.

    Per-channel affine maps commute with rotations, so the layer keeps equivariance.

    ``__call__(x, train)``: grids ``[N, C, 2B, 2B, 2B]`` in, normalised grids out; or a
    :class:`fused.Spectrum` / :class:`fused.S2Product` in and the affine map ``(scale [C],
    shift [C])`` out, which :func:`fused.pointwise` applies on its block grids.
    ``axis_name``: the mapped axis over which data-parallel training shards the batch (the
    statistics are then those of the whole batch).
    """
    momentum: float = 0.9
    epsilon: float = 1e-5
    use_scale: bool = True
    axis_name: str | None = None

    @nn.compact
    def __call__(self, x, train: bool):
        spectral = isinstance(x, (fused.Spectrum, fused.S2Product))
        channels = x.channels if spectral else x.shape[1]
        moments = None
        if train:
            moments = fused.moments(x) if spectral else transforms.so3_grid_moments(x)
        # Named as flax's nn.BatchNorm child was, so bundles trained with it keep loading.
        scale, shift = _HaarStatistics(self.momentum, self.epsilon, self.use_scale,
                                       self.axis_name, name="BatchNorm_0")(moments, channels,
                                                                          train)
        if spectral:
            return scale, shift
        return x * scale[:, None, None, None] + shift[:, None, None, None]


def haar_pool(x):
    """Rotation-invariant pooling ``[N, C, 2B, 2B, 2B] -> [N, C]`` (Haar mean)."""
    return transforms.so3_haar_mean(x)
