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

import functools

import numpy as np
import jax
import jax.numpy as jnp

from sphere_jax.spherical import so3, transforms

# Frame hypotheses (Compass's strongest modes) at least this far apart: a symmetric support's
# other frame is a half turn about an axis, far beyond the cells one peak spreads over.
MODE_SEPARATION_DEG = 45.0


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
    x = jnp.asarray(x_JxAxG, jnp.float32)
    return _refined(x, jnp.unravel_index(jnp.argmax(x), x.shape), temperature,
                    float(b if window is None else window))


def _refined(x, peak, temperature, h):
    """The Parzen-weighted mean index around cell ``peak`` of map ``x`` (cells at -inf weigh
    nothing)."""
    n = x.shape[0]
    idx = jnp.arange(n, dtype=jnp.float32)
    off_b = idx - peak[0]
    off_a = _circular_offset(idx, peak[1], n)
    off_g = _circular_offset(idx, peak[2], n)
    dist = jnp.sqrt(off_b[:, None, None] ** 2 + off_a[None, :, None] ** 2
                    + off_g[None, None, :] ** 2)
    # exp((x - x[peak])/τ) is 1 at the peak, whose window is 1: the sum is ≥ 1, never 0.
    top = jax.lax.stop_gradient(x[peak])
    w = jnp.exp((x - top) / temperature) * parzen_window(dist, h)
    w = w / jnp.sum(w)
    mean_off = jnp.stack([jnp.einsum("jag,j->", w, off_b), jnp.einsum("jag,a->", w, off_a),
                          jnp.einsum("jag,g->", w, off_g)])
    centre = jnp.stack(peak).astype(jnp.float32)
    return centre + mean_off


@functools.lru_cache(maxsize=None)
def _grid_rotations(b):
    """The SO(3) grid's rotations ``[8B³, 3, 3]``, built once in float64, kept in float32."""
    return np.asarray(so3.so3_grid_matrices(b).reshape(-1, 3, 3), np.float32)


def soft_argmax_modes(x_JxAxG, k, separation_deg=MODE_SEPARATION_DEG, temperature=1.0,
                      window=None):
    """The ``k`` strongest modes of one SO(3) map: ``(rotations [k, 3, 3], values [k])``,
    strongest first. The first is :func:`soft_argmax_rotation`'s; each next one is the
    arg-max of the cells farther than ``separation_deg`` (geodesic) from the peak cells of
    every earlier mode, refined by the same Parzen soft arg-max over the cells within half
    that angle of its own peak. A map with fewer separated cells repeats its last mode
    (value -inf)."""
    b = transforms.grid_bandwidth(x_JxAxG, 3, "x_JxAxG")
    x = jnp.asarray(x_JxAxG, jnp.float32)
    grid = jnp.asarray(_grid_rotations(b))
    cos_sep = float(np.cos(np.radians(separation_deg)))
    h = float(b if window is None else window)
    cos_half = float(np.cos(np.radians(separation_deg / 2)))
    rots, values, left = [], [], x.reshape(-1)
    for m in range(int(k)):
        i = jnp.argmax(left)
        peak = jnp.unravel_index(i, x.shape)
        # cos of the geodesic angle from every cell to this mode's: (tr(R_iᵀ R_n) - 1) / 2
        cos = (jnp.einsum("nij,ij->n", grid, grid[i]) - 1.0) / 2.0
        # A later mode is refined over the cells within half the separation of its peak only,
        # so that it cannot slide back towards an earlier one.
        cells = left if m == 0 else jnp.where(cos > cos_half, left, -jnp.inf)
        rot = so3.euler_to_matrix(*indices_to_euler(
            _refined(cells.reshape(x.shape), peak, temperature, h), b))
        rots.append(jnp.where(jnp.isfinite(left[i]), rot, rots[-1]) if rots else rot)
        values.append(left[i])
        left = jnp.where(cos > cos_sep, -jnp.inf, left)
    return jnp.stack(rots), jnp.stack(values)


def indices_to_euler(idx_3, b: int):
    """Continuous (β, α, γ) grid indices -> ZYZ angles ``(α, β, γ)`` on the SOFT grid."""
    beta = np.pi * (2 * idx_3[0] + 1) / (4 * b)
    return 2 * np.pi * idx_3[1] / (2 * b), beta, 2 * np.pi * idx_3[2] / (2 * b)


def soft_argmax_rotation(x_JxAxG, temperature=1.0, window=None):
    """Rotation matrix ``[3, 3]`` at the Parzen soft arg-max of an SO(3) map."""
    b = transforms.grid_bandwidth(x_JxAxG, 3, "x_JxAxG")
    idx = soft_argmax_indices(x_JxAxG, temperature, window)
    return so3.euler_to_matrix(*indices_to_euler(idx, b))
