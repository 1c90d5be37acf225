"""Compass (thesis 3.1): a learned local reference frame.

Patch -> spherical signal -> S2Conv + SO3Convs -> one SO(3) map -> Parzen soft-argmax ->
rotation F. Equivariance of the network makes ``F(R·P) ≈ R·F(P)``; the training signal is the
geodesic distance between the two sides, on a rotated and occluded copy of the patch.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from sphere_jax.models import losses
from sphere_jax.models.spec import ModelSpec
from sphere_jax.models.spherical import PatchSignal, SphericalStack
from sphere_jax.spherical import soft_argmax


class CompassOut(NamedTuple):
    rotations: jax.Array        # [N, 3, 3], columns x̂, ŷ, ẑ
    maps: jax.Array             # [N, 2B, 2B, 2B], the SO(3) map the rotation is read from


class Compass(nn.Module):
    """``__call__(patches [N, P, 3], train) -> CompassOut``."""
    bandwidths: Sequence[int] = (24, 24, 24, 24, 24)
    features: Sequence[int] = (40, 20, 10, 1)
    n_shells: int = 4
    temperature: float = 1.0
    window: float | None = None
    fused: bool = True          # spectral-domain path (sphere_jax.spherical.fused)
    axis_name: str | None = None    # data-parallel batch axis (layers.GridBatchNorm)

    @nn.compact
    def __call__(self, patches, train: bool = False):
        x = PatchSignal(self.bandwidths[0], self.n_shells)(patches)
        maps = SphericalStack(self.features, self.bandwidths, final_relu=False,
                              fused=self.fused, axis_name=self.axis_name)(x, train)[:, 0]
        rot = jax.vmap(lambda m: soft_argmax.soft_argmax_rotation(
            m, self.temperature, self.window))(maps)
        return CompassOut(rot, maps)


def with_copies(batch):
    """Network input of a batch with rotated copies: ``[2B, N, 3]``, originals first."""
    return jnp.concatenate([batch["patches"], batch["copies"]])


def angular_loss(rotations_2Bx3x3, batch):
    """Geodesic distance between the frame of each rotated copy and the rotated frame of its
    original (rotations of :func:`with_copies`' input)."""
    b = batch["patches"].shape[0]
    return losses.geodesic_loss(rotations_2Bx3x3[b:], batch["rotations"] @ rotations_2Bx3x3[:b])


def loss(out: CompassOut, batch, config):
    angular = angular_loss(out.rotations, batch)
    return angular, {"angular": angular}


def orient(model, variables, patches):
    return model.apply(variables, patches, train=False).rotations


def orient_modes(model, variables, patches, k):
    """The ``k`` strongest modes of each patch's SO(3) map ``[K, k, 3, 3]``, the first
    :func:`orient`'s (:func:`~sphere_jax.spherical.soft_argmax.soft_argmax_modes`)."""
    maps = model.apply(variables, patches, train=False).maps
    return jax.vmap(lambda m: soft_argmax.soft_argmax_modes(
        m, k, temperature=model.temperature, window=model.window)[0])(maps)


# Compass adapts with each batch's moments (no frozen_batch_norm): its validation angle fell
# faster so than with the bundle's running moments.
SPEC = ModelSpec(kind="compass", module=Compass, outputs=CompassOut, loss=loss,
                 inputs=with_copies, copies=True, orient=orient, orient_modes=orient_modes)
