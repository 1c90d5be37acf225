"""Parzen-weighted soft arg-max of an SO(3) map -> rotation (Compass, CONVENTIONS.md §7).

The hard arg-max picks the cell; around it, every cell is weighted by ``softmax(x/τ)`` times a
cubic B-spline Parzen window of its index distance to the arg-max (h cells wide), and the output
is the weighted mean grid index per axis, turned into ZYZ angles and a rotation matrix. The
window keeps far-away secondary modes (symmetric patches) from pulling the mean between them,
while the softmax makes the result differentiable in the map values.

α and γ are circular: offsets are taken on the circle, so a peak at the seam is averaged
correctly. The index distance is the Euclidean norm of the three per-axis offsets.
"""
from __future__ import annotations

import numpy as np
import jax
import jax.numpy as jnp

from sphere_jax.spherical import so3, transforms


def parzen_window(d, h):
    """Cubic B-spline window of distance ``d ≥ 0`` and width h: 1 at 0, 0 from h on."""
    u = d / h
    inner = 1.0 - 6.0 * u ** 2 * (1.0 - u)
    outer = 2.0 * (1.0 - u) ** 3
    return jnp.where(d <= h / 2, inner, jnp.where(d <= h, outer, 0.0))


def _circular_offset(idx, centre, n):
    """Signed offset of ``idx`` from ``centre`` on a circle of n cells, in [-n/2, n/2)."""
    return jnp.mod(idx - centre + n / 2, n) - n / 2


def soft_argmax_indices(x_JxAxG, temperature=1.0, window=None):
    """Continuous grid indices ``[3]`` = (β index, α index, γ index) of the peak of one SO(3)
    map ``[2B(β), 2B(α), 2B(γ)]``; ``window`` is h in cells (default B)."""
    b = transforms.grid_bandwidth(x_JxAxG, 3, "x_JxAxG")
    if x_JxAxG.ndim != 3:
        raise ValueError(f"x_JxAxG must be one SO(3) map [2B, 2B, 2B], got {x_JxAxG.shape}; "
                         f"vmap over batches")
    # Concrete maps only (under jit the check would need a callback): a NaN map has no peak,
    # and argmax would pick one anyway.
    if not isinstance(x_JxAxG, jax.core.Tracer):
        bad = int(np.size(x_JxAxG) - np.isfinite(np.asarray(x_JxAxG)).sum())
        if bad:
            raise ValueError(f"x_JxAxG must be finite; got {bad} non-finite value(s)")
    h = float(b if window is None else window)
    n = 2 * b
    x = jnp.asarray(x_JxAxG, jnp.float32)
    peak = jnp.unravel_index(jnp.argmax(x), x.shape)
    idx = jnp.arange(n, dtype=jnp.float32)
    off_b = idx - peak[0]
    off_a = _circular_offset(idx, peak[1], n)
    off_g = _circular_offset(idx, peak[2], n)
    dist = jnp.sqrt(off_b[:, None, None] ** 2 + off_a[None, :, None] ** 2
                    + off_g[None, None, :] ** 2)
    # exp((x - max)/τ) is 1 at the peak, whose window is 1: the sum is ≥ 1, never 0.
    w = jnp.exp((x - jax.lax.stop_gradient(jnp.max(x))) / temperature) * parzen_window(dist, h)
    w = w / jnp.sum(w)
    mean_off = jnp.stack([jnp.einsum("jag,j->", w, off_b), jnp.einsum("jag,a->", w, off_a),
                          jnp.einsum("jag,g->", w, off_g)])
    centre = jnp.stack(peak).astype(jnp.float32)
    return centre + mean_off


def indices_to_euler(idx_3, b: int):
    """Continuous (β, α, γ) grid indices -> ZYZ angles ``(α, β, γ)`` on the SOFT grid."""
    beta = np.pi * (2 * idx_3[0] + 1) / (4 * b)
    return 2 * np.pi * idx_3[1] / (2 * b), beta, 2 * np.pi * idx_3[2] / (2 * b)


def soft_argmax_rotation(x_JxAxG, temperature=1.0, window=None):
    """Rotation matrix ``[3, 3]`` at the Parzen soft arg-max of an SO(3) map."""
    b = transforms.grid_bandwidth(x_JxAxG, 3, "x_JxAxG")
    idx = soft_argmax_indices(x_JxAxG, temperature, window)
    return so3.euler_to_matrix(*indices_to_euler(idx, b))
