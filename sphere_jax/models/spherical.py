"""The spherical CNN trunk shared by the models: patch -> signal -> S2Conv -> SO3Conv ...."""
from __future__ import annotations

from typing import Sequence

import flax.linen as nn

from sphere_jax.spherical import fused, layers, signal


class PatchSignal(nn.Module):
    """Unit-ball patches ``[N, P, 3]`` -> spherical signals ``[N, K, 2B, 2B]`` (no parameters)."""
    bandwidth: int
    n_shells: int = 4

    def __call__(self, patches):
        return signal.patch_signals(patches, 1.0, self.bandwidth, self.n_shells)


class SphericalStack(nn.Module):
    """Convolutions with batch norm between: ``features[i]`` channels from bandwidth
    ``bandwidths[i]`` to ``bandwidths[i + 1]``. The first layer is an S2Conv when ``s2_first``;
    ReLU after every layer but the last unless ``final_relu``.

    With ``fused`` (the default, for training and inference) the layers are chained in the
    spectral domain (:mod:`~sphere_jax.spherical.fused`): the batch statistics come from the
    spectra (Haar moments, :class:`layers.GridBatchNorm`) and the pointwise step runs in
    cache-sized blocks that the backward pass recomputes. ``fused=False`` is the layer-by-layer
    reference on whole grids: same parameters, same outputs and gradients to round-off, several
    times the memory and time. On the fused path the input may also be a
    :class:`fused.Spectrum` of the input grids (analysed to at least ``bandwidths[1]``), e.g. a
    trunk shared by two stacks. ``axis_name``: see :class:`layers.GridBatchNorm`.
    """
    features: Sequence[int]
    bandwidths: Sequence[int]
    s2_first: bool = True
    final_relu: bool = True
    grid: str = "near_identity"
    fused: bool = True
    axis_name: str | None = None

    @nn.compact
    def __call__(self, x, train: bool):
        if len(self.bandwidths) != len(self.features) + 1:
            raise ValueError(f"bandwidths must have one entry more than features, got "
                             f"{self.bandwidths} and {self.features}")
        convs = [(layers.S2Conv if (i == 0 and self.s2_first) else layers.SO3Conv)(
            f, self.bandwidths[i], self.bandwidths[i + 1], self.grid)
            for i, f in enumerate(self.features)]
        norms = [layers.GridBatchNorm(axis_name=self.axis_name) for _ in self.features]
        last = len(self.features) - 1
        if not self.fused:
            if isinstance(x, fused.Spectrum):
                raise ValueError("a spectrum input needs the fused path (fused=True)")
            for i, (conv, norm) in enumerate(zip(convs, norms)):
                x = norm(conv(x), train)
                if i < last or self.final_relu:
                    x = nn.relu(x)
            return x
        if isinstance(x, fused.Spectrum):          # a shared trunk's output (SOUND)
            spec = fused.truncate(x, self.bandwidths[1])
        else:
            spec = fused.analyse(x, self.bandwidths[1], on_so3=not self.s2_first)
        for i, (conv, norm) in enumerate(zip(convs, norms)):
            h = conv(spec)
            scale, shift = norm(h, train)
            if i < last:
                spec = fused.pointwise(h, scale, shift, self.bandwidths[i + 2])
        y = fused.synthesise(h) * scale[:, None, None, None] + shift[:, None, None, None]
        return nn.relu(y) if self.final_relu else y
