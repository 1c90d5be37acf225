"""LEAD (thesis 4.1): an unsupervised rotation-equivariant descriptor.

Patch -> spherical encoder -> one-channel SO(3) map at bandwidth 4 (8³ = 512 values: the
descriptor, which rotates with the patch) -> folding decoder reconstructs the patch (Chamfer).
At test time the descriptor is rotated to a canonical pose by an LRF, in the spectral domain.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from sphere_jax.models import losses
from sphere_jax.models.folding import FoldingDecoder
from sphere_jax.models.spec import ModelSpec
from sphere_jax.models.spherical import PatchSignal, SphericalStack
from sphere_jax.spherical import transforms


class LeadOut(NamedTuple):
    maps: jax.Array             # [N, 2b, 2b, 2b] descriptor maps on SO(3)
    reconstructions: jax.Array  # [N, M, 3]


def canonical_descriptors(maps_Nx2bx2bx2b, frames_Nx3x3):
    """Descriptors ``[N, (2b)³]``: each SO(3) map rotated by the inverse of its LRF, so that
    it no longer depends on the patch's orientation (spectral rotation, exact for the
    band-limited maps)."""
    canon = jax.vmap(transforms.rotate_so3)(maps_Nx2bx2bx2b, jnp.swapaxes(frames_Nx3x3, 1, 2))
    return canon.reshape(canon.shape[0], -1)


class Lead(nn.Module):
    """``__call__(patches [N, P, 3], train) -> LeadOut``; the descriptor is the map
    flattened."""
    bandwidths: Sequence[int] = (24, 16, 12, 8, 6, 4)
    features: Sequence[int] = (40, 40, 40, 40, 1)
    n_shells: int = 4
    decoder_side: int = 35
    decoder_hidden: Sequence[int] = (514, 257, 128)
    # The seed puts ReLU after the last layer too; that makes the descriptor a non-band-limited
    # grid function, which Wigner-D rotation then only approximates (measured: 0.29 relative
    # error with it, see tests/models/test_lead.py). Off by default.
    final_relu: bool = False
    grid: str = "near_identity"     # kernel grids (correlation.make_grid; Table 4.5's axis)
    fused: bool = True          # spectral-domain path (sphere_jax.spherical.fused)
    axis_name: str | None = None    # data-parallel batch axis (layers.GridBatchNorm)

    def setup(self):
        self.signal = PatchSignal(self.bandwidths[0], self.n_shells)
        self.encoder = SphericalStack(self.features, self.bandwidths, final_relu=self.final_relu,
                                      grid=self.grid, fused=self.fused,
                                      axis_name=self.axis_name)
        self.decoder = FoldingDecoder(self.decoder_side, self.decoder_hidden,
                                      axis_name=self.axis_name)

    def encode(self, patches, train: bool = False):
        return self.encoder(self.signal(patches), train)[:, 0]

    def __call__(self, patches, train: bool = False):
        maps = self.encode(patches, train)
        return LeadOut(maps, self.decoder(maps.reshape(maps.shape[0], -1), train))


def reconstruction_loss(reconstructions, batch):
    """Mean Chamfer distance between the reconstructions and the patches the network read."""
    return jnp.mean(losses.chamfer_distance(reconstructions, batch["inputs"]))


def loss(out: LeadOut, batch, config):
    chamfer = reconstruction_loss(out.reconstructions, batch)
    return chamfer, {"chamfer": chamfer}


def describe(model, variables, patches, frames):
    maps = model.apply(variables, patches, method="encode")
    return canonical_descriptors(maps, frames)


SPEC = ModelSpec(kind="lead", module=Lead, outputs=LeadOut, loss=loss, describe=describe,
                 describe_frames=True, frozen_batch_norm=True)
