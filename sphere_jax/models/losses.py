"""Training losses: geodesic distance between rotations and Chamfer distance between clouds."""
from __future__ import annotations

import jax.numpy as jnp

from sphere_jax.spherical import so3


def geodesic_loss(pred_x33, target_x33):
    """Mean rotation angle (radians) between predicted and target rotations ``[..., 3, 3]``.

    Finite gradients everywhere, including at 0 and π (see :func:`so3.geodesic_distance`).
    """
    if pred_x33.shape != target_x33.shape or pred_x33.shape[-2:] != (3, 3):
        raise ValueError(f"pred_x33 and target_x33 must both be [..., 3, 3], got "
                         f"{pred_x33.shape} and {target_x33.shape}")
    return jnp.mean(so3.geodesic_distance(pred_x33, target_x33))


def chamfer_distance(a_Nx3, b_Mx3):
    """Symmetric Chamfer distance (seed eq. 2.7): mean squared distance from each point of one
    cloud to its nearest neighbour in the other, summed over both directions. Batched over
    leading axes; dense ``[..., N, M]`` distances (patches are small)."""
    if a_Nx3.shape[-1] != 3 or b_Mx3.shape[-1] != 3 or a_Nx3.shape[:-2] != b_Mx3.shape[:-2]:
        raise ValueError(f"a_Nx3 and b_Mx3 must be [..., N, 3] and [..., M, 3] with the same "
                         f"leading axes, got {a_Nx3.shape} and {b_Mx3.shape}")
    if a_Nx3.shape[-2] == 0 or b_Mx3.shape[-2] == 0:
        raise ValueError(f"chamfer_distance needs non-empty clouds, got {a_Nx3.shape} and "
                         f"{b_Mx3.shape}")
    # |a|² + |b|² - 2ab is a GEMM; clamp the rounding below zero.
    d2 = (jnp.sum(a_Nx3 ** 2, -1)[..., :, None] + jnp.sum(b_Mx3 ** 2, -1)[..., None, :]
          - 2.0 * jnp.einsum("...nd,...md->...nm", a_Nx3, b_Mx3))
    d2 = jnp.maximum(d2, 0.0)
    return jnp.mean(jnp.min(d2, -1), -1) + jnp.mean(jnp.min(d2, -2), -1)
