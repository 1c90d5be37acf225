"""A learned x̂ on the support's normal, after LRF-Net (Zhu et al. 2020).

ẑ is the normal of the support (:func:`~sphere_jax.models.flare.support_normal`, FLARE's: it
repeats on two thirds of corresponding keypoints, where a learned ẑ does not). x̂ is a weighted
sum of the neighbours' projections onto the tangent plane, the weights a softmax over scores
that a small network gives each neighbour from rotation-invariant features — its distance to
the keypoint, its height above the tangent plane, its distance from the normal — and the
patch's context (their max-pool). The weights are invariant, so the frame turns exactly with
the patch; what training teaches is which neighbours keep the direction when the support is
drawn again and occluded: the loss is Compass's, the geodesic distance between the frame of a
rotated, occluded copy and the rotated frame of its original.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from sphere_jax.models import compass, flare
from sphere_jax.models.spec import ModelSpec


class LrfNetOut(NamedTuple):
    rotations: jax.Array        # [N, 3, 3], columns x̂, ŷ, ẑ
    weights: jax.Array          # [N, P], each patch's neighbour weights (sum 1)


def invariant_features(patches_NxPx3, z_Nx3):
    """``([N, P, 3] features, [N, P, 3] tangent projections)``: per neighbour its distance to
    the keypoint, its height above the tangent plane and its distance from the normal."""
    height = jnp.einsum("npk,nk->np", patches_NxPx3, z_Nx3)
    tangent = patches_NxPx3 - height[..., None] * z_Nx3[:, None]
    features = jnp.stack([jnp.linalg.norm(patches_NxPx3, axis=-1), height,
                          jnp.linalg.norm(tangent, axis=-1)], -1)
    return features, tangent


class LrfNet(nn.Module):
    """``__call__(unit patches [N, P, 3], train) -> LrfNetOut``."""
    point: Sequence[int] = (32, 64)         # per-neighbour layers, before the max-pool
    score: Sequence[int] = (64, 32)         # per-neighbour layers with the patch's context
    normal_radius: float = 0.5              # of the support: the points ẑ is fitted to
    axis_name: str | None = None            # no batch norm: nothing to average

    @nn.compact
    def __call__(self, patches, train: bool = False):
        z = jax.vmap(flare.support_normal, (0, None))(patches, self.normal_radius)
        features, tangent = invariant_features(patches, z)
        real = jnp.linalg.norm(patches, axis=-1) > 0          # the keypoint itself: no say
        e = features
        for width in self.point:
            e = nn.relu(nn.Dense(width)(e))
        context = jnp.max(jnp.where(real[..., None], e, -jnp.inf), axis=1, keepdims=True)
        h = jnp.concatenate([e, jnp.broadcast_to(context, e.shape[:2] + context.shape[2:])], -1)
        for width in self.score:
            h = nn.relu(nn.Dense(width)(h))
        scores = jnp.where(real, nn.Dense(1)(h)[..., 0], -jnp.inf)
        weights = jax.nn.softmax(scores, axis=-1)
        x = jnp.einsum("np,npk->nk", weights, tangent)
        x = x / jnp.maximum(jnp.linalg.norm(x, axis=-1, keepdims=True), 1e-9)
        return LrfNetOut(jnp.stack([x, jnp.cross(z, x), z], -1), weights)


def loss(out: LrfNetOut, batch, config):
    angular = compass.angular_loss(out.rotations, batch)
    return angular, {"angular": angular}


def orient(model, variables, patches):
    return model.apply(variables, patches, train=False).rotations


SPEC = ModelSpec(kind="lrf_net", module=LrfNet, outputs=LrfNetOut, loss=loss,
                 inputs=compass.with_copies, copies=True, orient=orient, infer_slice=None)
