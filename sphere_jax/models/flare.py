"""Hand-crafted local reference frames (JAX, vmappable over patches).

An LRF is a 3×3 matrix whose columns are the local x̂, ŷ, ẑ axes in world coordinates
(CONVENTIONS.md §5); canonical coordinates of a patch are ``p @ F`` (= ``Fᵀ p`` per point).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp


def support_normal(patch_Nx3, within=0.5):
    """FLARE's ẑ of a patch in local coordinates (keypoint at 0): the normal of the plane
    fitted (PCA) to the points within ``within`` of the keypoint (all points where fewer than
    3 are), turned away from the patch's mass. ``[3]``; equivariant: a turned patch turns it."""
    p = jnp.asarray(patch_Nx3, jnp.float32)
    r = jnp.linalg.norm(p, axis=-1)
    inner = (r <= within) & (r > 0)
    inner = jnp.where(jnp.sum(inner) >= 3, inner, r > 0)       # too few: fit to all points
    w = inner.astype(p.dtype)
    mean = jnp.sum(w[:, None] * p, 0) / jnp.sum(w)
    d = (p - mean) * w[:, None]
    _, vecs = jnp.linalg.eigh(d.T @ d)
    z = vecs[:, 0]
    return jnp.where(jnp.sum(p @ z) > 0, -z, z)


def flare(patch_Nx3, radius=1.0, normal_radius=0.5, margin=0.85):
    """FLARE (Petrelli & Di Stefano 2012) of a patch in local coordinates (keypoint at 0).

    ẑ: normal of the plane fitted (PCA) to the points within ``normal_radius·radius``, turned
    away from the patch's mass (no input normals needed). x̂: towards the point of the
    periphery (beyond ``margin·radius``) that rises highest above the tangent plane, projected
    onto it. Returns ``[3, 3]`` (columns x̂, ŷ, ẑ).
    """
    p = jnp.asarray(patch_Nx3, jnp.float32)
    r = jnp.linalg.norm(p, axis=-1)
    z = support_normal(p, normal_radius * radius)
    height = p @ z
    periphery = r > margin * radius
    periphery = jnp.where(jnp.any(periphery), periphery, r > 0)
    best = jnp.argmax(jnp.where(periphery, height, -jnp.inf))
    x = p[best] - height[best] * z
    x = x / jnp.maximum(jnp.linalg.norm(x), 1e-12)
    return jnp.stack([x, jnp.cross(z, x), z], 1)


def flare_orient(patches_BxNx3):
    """Patches ``[B, N, 3]`` in their own FLARE frames (canonical coordinates ``p @ F``)."""
    frames = jax.vmap(flare)(patches_BxNx3)
    return jnp.einsum("bnk,bkj->bnj", patches_BxNx3, frames)
