"""Rotations and sampling grids: the one module that owns the conventions.

Conventions (CONVENTIONS.md §2–§3), used by every other module:

* Points are ``[N, 3]``; a rotation acts actively, ``p' = R p``.
* ZYZ Euler angles: ``R(α, β, γ) = Rz(α) · Ry(β) · Rz(γ)``, right-handed.
* Sphere: ``x(β, α) = (sin β cos α, sin β sin α, cos β) = R(α, β, 0) ẑ``.
* SOFT / Driscoll–Healy grids of bandwidth B, 2B samples per axis:
  ``β_j = π(2j+1)/(4B)``, ``α_k = γ_k = 2πk/(2B)``.
  Layouts are **channels first**: S2 ``[..., C, 2B(β), 2B(α)]``, SO(3)
  ``[..., C, 2B(β), 2B(α), 2B(γ)]``. Measured on the 2-core CPU: transforms over the last
  (contiguous) grid axes are about 3x faster than over axes followed by a channel axis.
* Geodesic distance ``θ = arccos((tr(AᵀB) − 1)/2)``.

Functions taking angles or matrices are jnp (jit/vmap/grad-able). Grid and quadrature builders
return float64 numpy: they are constants, built once outside traced code.
"""
from __future__ import annotations

import numpy as np
import jax
import jax.numpy as jnp

# Inside ±1 so that d(arccos)/dx = -1/sqrt(1 - x²) stays finite at θ = 0 and θ = π.
_COS_CLIP = 1.0 - 1e-7


def _rz(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.stack([jnp.stack([c, -s, z], -1), jnp.stack([s, c, z], -1),
                      jnp.stack([z, z, o], -1)], -2)


def _ry(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.stack([jnp.stack([c, z, s], -1), jnp.stack([z, o, z], -1),
                      jnp.stack([-s, z, c], -1)], -2)


def euler_to_matrix(alpha, beta, gamma):
    """ZYZ Euler angles ``[...]`` (radians) -> rotation matrices ``[..., 3, 3]``."""
    return _rz(alpha) @ _ry(beta) @ _rz(gamma)


def matrix_to_euler(rot_x33):
    """Rotation matrices ``[..., 3, 3]`` -> ZYZ angles ``(α, β, γ)``, each ``[...]``.

    α, γ ∈ [0, 2π), β ∈ [0, π]. At the gimbal-locked poles (β = 0 or π) only α ± γ is defined;
    γ = 0 is returned there.
    """
    r = jnp.asarray(rot_x33)
    sin_beta = jnp.hypot(r[..., 0, 2], r[..., 1, 2])
    beta = jnp.arctan2(sin_beta, r[..., 2, 2])
    regular = sin_beta > 1e-6
    alpha = jnp.where(regular, jnp.arctan2(r[..., 1, 2], r[..., 0, 2]),
                      jnp.arctan2(r[..., 1, 0], r[..., 0, 0] * jnp.sign(r[..., 2, 2] + 0.5)))
    gamma = jnp.where(regular, jnp.arctan2(r[..., 2, 1], -r[..., 2, 0]), 0.0)
    two_pi = 2 * jnp.pi
    return jnp.mod(alpha, two_pi), beta, jnp.mod(gamma, two_pi)


def random_rotation(key, shape=()):
    """Rotations ``[*shape, 3, 3]`` uniform (Haar) on SO(3), from QR of a Gaussian."""
    g = jax.random.normal(key, tuple(shape) + (3, 3))
    q, r = jnp.linalg.qr(g)
    # Fix the sign ambiguity of QR (Mezzadri 2007) so the distribution is exactly Haar ...
    q = q * jnp.sign(jnp.diagonal(r, axis1=-2, axis2=-1))[..., None, :]
    # ... and map O(3) \ SO(3) onto SO(3) by flipping one column.
    det = jnp.linalg.det(q)
    return q.at[..., :, 0].multiply(det[..., None])


def geodesic_distance(a_x33, b_x33):
    """Angle ``[...]`` (radians, in [0, π]) of the relative rotation ``AᵀB``.

    Differentiable everywhere: the cosine is clipped slightly inside ±1.
    """
    shapes = tuple(np.shape(a_x33)), tuple(np.shape(b_x33))
    if any(s[-2:] != (3, 3) for s in shapes):
        raise ValueError(f"a_x33 and b_x33 must be rotations [..., 3, 3]; got shapes {shapes}")
    cos = (jnp.einsum("...ij,...ij->...", a_x33, b_x33) - 1.0) / 2.0
    return jnp.arccos(jnp.clip(cos, -_COS_CLIP, _COS_CLIP))


def geodesic_distance_np(a_x33, b_x33):
    """:func:`geodesic_distance` for evaluations: float64 numpy, clipped exactly to ±1 (no
    gradient to protect), NaN where either matrix is NaN."""
    a, b = np.asarray(a_x33, np.float64), np.asarray(b_x33, np.float64)
    cos = (np.einsum("...ij,...ij->...", a, b) - 1.0) / 2.0
    return np.arccos(np.clip(cos, -1.0, 1.0))


def sphere_points(beta, alpha):
    """Unit vectors ``[..., 3]`` at polar angle β (from +z) and azimuth α (from +x)."""
    sb = jnp.sin(beta)
    return jnp.stack([sb * jnp.cos(alpha), sb * jnp.sin(alpha), jnp.cos(beta)], -1)


# ----------------------------------------------------------------------------------------------
# SOFT grids and quadrature (float64 numpy constants).
# ----------------------------------------------------------------------------------------------

def check_rotation(rot_33, name="rot_33", tol=1e-3):
    """``rot_33`` if it is a ``[3, 3]`` rotation: the shape always, and RᵀR = I, det R = +1
    within ``tol`` when its values are concrete (not under jit); an error naming ``name``
    otherwise (a wrong shape would fail deep in an einsum, a scaled matrix silently scale
    the signal)."""
    shape = tuple(getattr(rot_33, "shape", np.shape(rot_33)))
    if shape != (3, 3):
        raise ValueError(f"{name} must be a rotation matrix [3, 3]; got shape {shape}")
    if isinstance(rot_33, jax.core.Tracer):
        return rot_33
    r = np.asarray(rot_33, np.float64)
    err = np.abs(r.T @ r - np.eye(3)).max() if np.isfinite(r).all() else np.inf
    if err > tol or abs(np.linalg.det(r) - 1) > tol:
        raise ValueError(f"{name} must be a rotation (RᵀR = I and det R = +1 within {tol}); "
                         f"got |RᵀR − I| = {err:.3g}, det R = {np.linalg.det(r):.4g}")
    return rot_33


def check_bandwidth(b, name="bandwidth"):
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or b < 1:
        raise ValueError(f"{name} must be a positive integer, got {b!r}")
    return int(b)


def grid_beta(b):
    """``β_j = π(2j+1)/(4B)``, j ∈ [0, 2B): float64 ``[2B]``."""
    b = check_bandwidth(b)
    return np.pi * (2 * np.arange(2 * b) + 1) / (4 * b)


def grid_alpha(b):
    """``α_k = 2πk/(2B)``, k ∈ [0, 2B): float64 ``[2B]`` (also the γ grid)."""
    b = check_bandwidth(b)
    return 2 * np.pi * np.arange(2 * b) / (2 * b)


def s2_grid(b):
    """Grid angles ``(β, α)``, each float64 ``[2B, 2B]`` (indexing β, α)."""
    return np.meshgrid(grid_beta(b), grid_alpha(b), indexing="ij")


def so3_grid(b):
    """Grid angles ``(α, β, γ)``, each float64 ``[2B(β), 2B(α), 2B(γ)]``."""
    beta, alpha, gamma = np.meshgrid(grid_beta(b), grid_alpha(b), grid_alpha(b), indexing="ij")
    return alpha, beta, gamma


def so3_grid_matrices(b):
    """Rotation matrices of the SO(3) grid, float64 ``[2B, 2B, 2B, 3, 3]``."""
    return euler_to_matrix_np(*so3_grid(b))


def euler_to_matrix_np(alpha, beta, gamma):
    """float64 numpy twin of :func:`euler_to_matrix`, for building constants."""
    def rz(a):
        c, s = np.cos(a), np.sin(a)
        o, z = np.ones_like(a), np.zeros_like(a)
        return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                         np.stack([z, z, o], -1)], -2)

    def ry(a):
        c, s = np.cos(a), np.sin(a)
        o, z = np.ones_like(a), np.zeros_like(a)
        return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                         np.stack([-s, z, c], -1)], -2)

    return rz(np.asarray(alpha, np.float64)) @ ry(np.asarray(beta, np.float64)) @ rz(
        np.asarray(gamma, np.float64))


def quadrature_weights(b):
    """SOFT quadrature weights ``w_j`` over β, float64 ``[2B]``.

    ``Σ_j w_j g(β_j) = ∫_0^π g(β) sin β dβ`` exactly for g a polynomial in cos β of degree < 2B
    (so products of two band-B Wigner-d functions are integrated exactly).
    """
    b = check_bandwidth(b)
    j = np.arange(2 * b)[:, None]
    k = np.arange(b)[None, :]
    s = np.sum(np.sin((2 * j + 1) * (2 * k + 1) * np.pi / (4 * b)) / (2 * k + 1), axis=1)
    return (2.0 / b) * np.sin(np.pi * (2 * np.arange(2 * b) + 1) / (4 * b)) * s


def haar_weights(b):
    """Weights ``[2B(β)]`` that average a function over the SO(3) grid: they sum to 1 / (2B)²,
    so ``Σ_{jkl} w_j f_{jkl}`` is the Haar mean of f (exact for band-B functions)."""
    return quadrature_weights(b) / (2.0 * (2 * b) ** 2)
