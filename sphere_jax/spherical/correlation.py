"""S2 and SO(3) correlation with localized kernels, as pure functions.

A kernel is a set of weights on a small grid of points ``g`` (on S2, or rotations in SO(3)).
Correlating a signal with it gives, for every rotation R of the output SO(3) grid,

    h(R) = Σ_g w_g f(R g)   (CONVENTIONS.md §4: (ψ ⋆ f)(R) = ∫ f(x) ψ(R⁻¹x) dx, ψ = Σ w_g δ_g)

evaluated exactly for the band-limited f, in the spectral domain (Cohen et al. 2018):

* S2:    ``h^l_{mn} = f̂^l_m · Z^l_n``,            ``Z^l_n = Σ_g w_g Y^l_n(g)``
* SO(3): ``h^l_{mn} = Σ_k f̂^l_{mk} · W^l_{kn}``,  ``W^l_{kn} = Σ_g w_g conj(D^l_{nk}(g))``

with coefficients as in :mod:`transforms`. Both are equivariant: ``h[L_R f] = L_R h[f]``.

Kernel spectra are one real GEMM of the weights ``[G, C·D]`` with a constant table of the basis
functions at the G grid points (n ≥ 0 half only: the kernel is real).

The SO(3) product is done per degree as one real GEMM (real and imaginary parts stacked), since
XLA on CPU runs one big GEMM on all cores but batched small matmuls on one.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import jax.numpy as jnp

from sphere_jax.spherical import so3, transforms, wigner


# ----------------------------------------------------------------------------------------------
# Kernel grids (hashable, so they can be flax module attributes)
# ----------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class KernelGrid:
    """Points ``(β_b, α_a, γ_p + gamma_shift·α_a)``; ``gamma=None`` for an S2 grid."""
    beta: tuple
    alpha: tuple
    gamma: tuple | None = None
    gamma_shift: float = 0.0

    @property
    def on_so3(self) -> bool:
        return self.gamma is not None

    @property
    def shape(self) -> tuple:
        """Weight-grid shape: ``(n_beta, n_alpha)`` or ``(n_beta, n_alpha, n_gamma)``."""
        s = (len(self.beta), len(self.alpha))
        return s + (len(self.gamma),) if self.on_so3 else s

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def points(self):
        """Euler angles ``(α, β, γ)`` of every grid point, float64 arrays of :attr:`shape`."""
        if not self.on_so3:
            b, a = np.meshgrid(self.beta, self.alpha, indexing="ij")
            return a, b, np.zeros_like(a)
        b, a, p = np.meshgrid(self.beta, self.alpha, self.gamma, indexing="ij")
        return a, b, p + self.gamma_shift * a


def _grid(beta, alpha, gamma=None, shift=0.0):
    tup = lambda v: tuple(float(x) for x in np.atleast_1d(v))
    return KernelGrid(tup(beta), tup(alpha), None if gamma is None else tup(gamma), float(shift))


def s2_near_identity_grid(max_beta=np.pi / 8, n_alpha=8, n_beta=3) -> KernelGrid:
    """Rings around the north pole: ``β = k·max_β/n_β`` (k = 1..n_β), n_α azimuths each."""
    return _grid(np.arange(1, n_beta + 1) * max_beta / n_beta,
                 np.linspace(0, 2 * np.pi, n_alpha, endpoint=False))


def s2_equatorial_grid(max_beta=0.0, n_alpha=32, n_beta=1) -> KernelGrid:
    """A band around the equator: ``β = π/2 + linspace(-max_β, max_β, n_β)``."""
    return _grid(np.pi / 2 + np.linspace(-max_beta, max_beta, n_beta),
                 np.linspace(0, 2 * np.pi, n_alpha, endpoint=False))


def so3_near_identity_grid(max_beta=np.pi / 8, max_gamma=2 * np.pi, n_alpha=8, n_beta=3,
                           n_gamma=8) -> KernelGrid:
    """Rotations near the identity (s2cnn's grid): ``γ = γ' − α``, γ' ∈ [-max_γ, max_γ]."""
    return _grid(np.arange(1, n_beta + 1) * max_beta / n_beta,
                 np.linspace(0, 2 * np.pi, n_alpha, endpoint=False),
                 np.linspace(-max_gamma, max_gamma, n_gamma, endpoint=True), shift=-1.0)


def so3_equatorial_grid(max_beta=0.0, max_gamma=np.pi / 8, n_alpha=32, n_beta=1,
                        n_gamma=2) -> KernelGrid:
    """Rotations taking ẑ to the equator band, with a small spread in γ."""
    return _grid(np.pi / 2 + np.linspace(-max_beta, max_beta, n_beta),
                 np.linspace(0, 2 * np.pi, n_alpha, endpoint=False),
                 np.linspace(-max_gamma, max_gamma, n_gamma, endpoint=True))


def make_grid(kind: str, on_so3: bool, bandwidth: int | None = None) -> KernelGrid:
    """Named grids of CONVENTIONS.md §7: ``'near_identity'`` or ``'equatorial'`` (n_α = 2B)."""
    if kind == "near_identity":
        return so3_near_identity_grid() if on_so3 else s2_near_identity_grid()
    if kind == "equatorial":
        if bandwidth is None:
            raise ValueError("the equatorial grid needs bandwidth (n_alpha = 2B)")
        n_alpha = 2 * so3.check_bandwidth(bandwidth)
        return so3_equatorial_grid(n_alpha=n_alpha) if on_so3 else s2_equatorial_grid(
            n_alpha=n_alpha)
    raise ValueError(f"grid must be 'near_identity' or 'equatorial', got {kind!r}")


# ----------------------------------------------------------------------------------------------
# Kernel spectra
# ----------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _s2_kernel_table(grid: KernelGrid, lmax: int):
    """``Y^l_n(g)`` for n ≥ 0 as float32 ``[L·2·L (l, re/im, n), G]``."""
    alpha, beta, _ = grid.points()
    d = wigner.wigner_d_dense(lmax, beta.ravel())[..., lmax - 1:, lmax - 1]   # [g, l, n≥0]
    d = d * np.sqrt((2 * np.arange(lmax) + 1) / (4 * np.pi))[:, None]
    y = d * np.exp(1j * alpha.ravel()[:, None, None] * np.arange(lmax))
    t = np.stack([y.real, y.imag], axis=2)                                    # [g, l, 2, n]
    return np.ascontiguousarray(t.reshape(t.shape[0], -1).T).astype(np.float32)


def s2_kernel_spectrum(w, grid: KernelGrid, lmax: int):
    """Weights ``[n_β, n_α, C, D]`` -> ``Z^l_n = Σ_g w_g Y^l_n(g)`` as the real block matrix
    ``[L(l), 2(s), C, 2(r), L(n≥0), D]`` that multiplies (re, im) of the input into (re, im) of
    the output: ``[[Re Z, Im Z], [-Im Z, Re Z]]``."""
    _check_weights(w, grid)
    c, d = w.shape[-2:]
    z = (_s2_kernel_table(grid, lmax) @ jnp.reshape(w, (grid.size, c * d))).reshape(
        lmax, 2, lmax, c, d)
    z = jnp.transpose(z, (0, 3, 1, 2, 4))                                     # [l, C, r, n, D]
    swapped = jnp.stack([-z[:, :, 1], z[:, :, 0]], 2)
    return jnp.stack([z, swapped], 1)


@functools.lru_cache(maxsize=None)
def _so3_kernel_table(grid: KernelGrid, lmax: int):
    """``conj D^l_{nk}(g)`` for n ≥ 0, all degrees stacked: float32 ``[Σ_l (2l+1)·2·(l+1), G]``
    with per-degree rows ordered (k, re/im, n)."""
    alpha, beta, gamma = (a.ravel() for a in grid.points())
    blocks = []
    for l in range(lmax):
        dd = wigner.wigner_D(l, alpha, beta, gamma).conj()[:, l:, :]          # [g, n≥0, k]
        t = np.stack([dd.real, dd.imag], axis=1).transpose(3, 1, 2, 0)        # [k, 2, n, g]
        blocks.append(t.reshape(-1, len(alpha)))
    return np.concatenate(blocks, 0).astype(np.float32)


def so3_kernel_spectrum(w, grid: KernelGrid, lmax: int) -> list:
    """Weights ``[n_β, n_α, n_γ, C, D]`` -> per degree l the real float32 array
    ``[2l+1 (k), 2 (re/im), l+1 (n ≥ 0), C, D]`` of ``W^l_{kn} = Σ_g w_g conj D^l_{nk}(g)``."""
    _check_weights(w, grid)
    c, d = w.shape[-2:]
    rows = _so3_kernel_table(grid, lmax) @ jnp.reshape(w, (grid.size, c * d))
    out, start = [], 0
    for l in range(lmax):
        size = (2 * l + 1) * 2 * (l + 1)
        out.append(rows[start:start + size].reshape(2 * l + 1, 2, l + 1, c, d))
        start += size
    return out


def _check_weights(w, grid: KernelGrid):
    expect = grid.shape
    if tuple(w.shape[:len(expect)]) != expect or w.ndim != len(expect) + 2:
        raise ValueError(f"kernel weights must have shape {expect} + (C_in, C_out), "
                         f"got {tuple(w.shape)}")


# ----------------------------------------------------------------------------------------------
# Per-degree products
# ----------------------------------------------------------------------------------------------

def _full_m(f, lmax):
    """S2 spectrum ``[L(m≥0), ...(l), 2, ...]`` -> ``[2L-1(m), ...]`` by
    ``f̂_{-m} = (-1)^m conj f̂_m`` (re/im on axis 2)."""
    sign = (-1.0) ** np.arange(lmax - 1, 0, -1)                       # m = L-1..1
    conj = np.array([1.0, -1.0])
    neg = jnp.flip(f[1:], 0) * (sign[:, None, None, None, None] * conj[None, None, :, None, None])
    return jnp.concatenate([neg, f], 0)


def s2_spectral_product(f, zb):
    """S2 spectra ``[L(m≥0), L(l), 2, N, C]`` × kernel blocks ``[L, 2, C, 2, L, D]`` -> SO(3)
    spectra ``[2L-1(m), L(n≥0), L(l), 2, N, D]``: ``h^l_{mn} = Σ_c f̂^l_m Z^l_n``.

    One product with contraction over (re/im, C), dense over all degrees (zeros where
    |m| > l are carried along: with C = 4 the step is memory bound, not flop bound).
    """
    lmax = f.shape[0]
    return jnp.einsum("mlsxc,lscrnd->mnlrxd", _full_m(f, lmax), zb)


def s2_product_moments(f, zb):
    """Haar mean and mean square ``([N·D], [N·D])`` of the SO(3) signals whose spectra are
    :func:`s2_spectral_product` ``(f, zb)`` (``f``: ``[L(m≥0), L(l), 2, N, C]``; ``zb``:
    ``[L, 2, C, 2, L, D]``), without forming it: what :func:`transforms.so3_moments` gives of
    the product, to float round-off.

    Per degree ``h_{mn} = Σ_c f_{mc} Z_{nc}``, so ``Σ_{mn} w_n |h_{mn}|² = Σ_{cc'} F_{cc'}
    G_{cc'}`` with the C × C Gram matrices ``F = Σ_m f_{mc} conj f_{mc'}`` (per patch) and
    ``G = Σ_n w_n Z_{nc} conj Z_{nc'}`` (per output channel): a few thousand products per
    patch where the product itself is ``2(2L-1)L²·D`` floats to write and read back (batch
    norm's statistics in training)."""
    lmax = f.shape[0]
    full = _full_m(f, lmax)                                            # [m, l, s, N, C]
    fr, fi = full[:, :, 0], full[:, :, 1]
    gram_f = lambda a, b: jnp.einsum("mlxc,mlxe->lxce", a, b)
    f_re, f_im = gram_f(fr, fr) + gram_f(fi, fi), gram_f(fi, fr) - gram_f(fr, fi)
    zr, zi = zb[:, 0, :, 0], zb[:, 0, :, 1]                           # Z: [l, C, n, D]
    w = jnp.asarray(np.where(np.arange(lmax) == 0, 1.0, 2.0), jnp.float32)  # n > 0 twice
    gram_z = lambda a, b: jnp.einsum("lcnd,lend,n->ldce", a, b, w)
    z_re, z_im = gram_z(zr, zr) + gram_z(zi, zi), gram_z(zi, zr) - gram_z(zr, zi)
    inv = jnp.asarray(1.0 / (2 * np.arange(lmax) + 1), jnp.float32)
    mean_sq = (jnp.einsum("lxce,ldce,l->xd", f_re, z_re, inv)
               - jnp.einsum("lxce,ldce,l->xd", f_im, z_im, inv))
    # Degree 0: h_00 = Σ_c f_0 Z_0, its real part the mean.
    mean = (jnp.einsum("xc,cd->xd", f[0, 0, 0], zr[0, :, 0])
            - jnp.einsum("xc,cd->xd", f[0, 0, 1], zi[0, :, 0]))
    return mean.reshape(-1), mean_sq.reshape(-1)


def _full_k(f_l, l):
    """``[2l+1(m), l+1(k≥0), 2, N, C]`` -> ``[2l+1(m), 2l+1(k), 2, N, C]`` by
    ``f̂_{m,-k} = (-1)^{m-k} conj f̂_{-m,k}``."""
    if l == 0:
        return f_l
    m = np.arange(-l, l + 1)[:, None]
    k = np.arange(l, 0, -1)[None, :]                                   # k = -l..-1 -> |k|
    sign = ((-1.0) ** (m - k))[:, :, None] * np.array([1.0, -1.0])[None, None, :]
    neg = jnp.flip(f_l[:, 1:], (0, 1)) * sign[..., None, None]
    return jnp.concatenate([neg, f_l], 1)


def so3_spectral_product(f, w_list):
    """SO(3) spectra ``[2L-1(m), L(k≥0), L(l), 2, N, C]`` × per-degree ``W^l`` -> spectra
    ``[2L-1(m), L(n≥0), L(l), 2, N, D]``: ``h^l_{mn} = Σ_{k,c} f̂^l_{mk} W^l_{kn}``.

    Degree l is one real GEMM ``[2(2l+1)N, (2l+1)C] @ [(2l+1)C, 2(l+1)D]``: real and imaginary
    parts of the input stacked on the rows, those of the kernel on the columns; the four
    partial products are combined after.
    """
    lmax = f.shape[1]
    out = []
    for l, w_l in enumerate(w_list):
        pad = lmax - 1 - l
        f_l = _full_k(f[pad:lmax + l, :l + 1, l], l)                   # [m, k, s, N, C]
        o = jnp.einsum("mksxc,ktncd->smxtnd", f_l, w_l)
        h = jnp.stack([o[0, :, :, 0] - o[1, :, :, 1], o[0, :, :, 1] + o[1, :, :, 0]], 2)
        h = jnp.transpose(h, (0, 3, 2, 1, 4))                           # [m, n, r, N, D]
        out.append(jnp.pad(h, ((pad, pad), (0, pad), (0, 0), (0, 0), (0, 0))))
    return jnp.stack(out, 2)


def product_flops(kind: str, batch: int, lmax: int, c_in: int, c_out: int) -> int:
    """Real flops of the useful per-degree complex products (8 per complex multiply-add)."""
    ls = np.arange(lmax)
    if kind == "s2":
        return int(8 * batch * c_in * c_out * np.sum((ls + 1) * (2 * ls + 1)))
    return int(8 * batch * c_in * c_out * np.sum((ls + 1) * (2 * ls + 1) ** 2))


# ----------------------------------------------------------------------------------------------
# Whole correlations
# ----------------------------------------------------------------------------------------------

def _flatten_batch(x, event_ndim):
    lead = x.shape[:x.ndim - event_ndim]
    return x.reshape((-1,) + x.shape[x.ndim - event_ndim:]), lead


def _check_channels(x, w, grid_ndim):
    if x.ndim < grid_ndim + 1 or x.shape[-grid_ndim - 1] != w.shape[-2]:
        raise ValueError(f"x must have shape [..., C_in={w.shape[-2]}, "
                         f"{', '.join(['2B'] * grid_ndim)}], got {tuple(x.shape)}")


def _spectral_correlate(x, w, grid, b_out, on_so3):
    grid_ndim = 3 if on_so3 else 2
    b_in = transforms.grid_bandwidth(x, grid_ndim)
    _check_channels(x, w, grid_ndim)
    _check_band_change(b_in, b_out)
    xf, lead = _flatten_batch(jnp.asarray(x, jnp.float32), grid_ndim + 1)
    n, c = xf.shape[:2]
    x_flat = xf.reshape((n * c,) + xf.shape[2:])
    analysis = transforms.so3_analysis if on_so3 else transforms.s2_analysis
    h = spectral_product(analysis(x_flat, b_out), c, w, grid, b_out, on_so3)
    y = transforms.so3_synthesis(h, b_out)
    return y.reshape(lead + (w.shape[-1],) + (2 * b_out,) * 3)


def spectral_product(f, channels: int, w, grid: KernelGrid, lmax: int, on_so3: bool):
    """Internal S2 or SO(3) spectrum ``[..., N·C]`` (C = ``channels`` minor) -> the SO(3)
    spectrum ``[2L-1, L, L, 2, N·D]`` of its correlation with the kernel ``w``."""
    f = f.reshape(f.shape[:-1] + (-1, channels))
    if on_so3:
        h = so3_spectral_product(f, so3_kernel_spectrum(w, grid, lmax))
    else:
        h = s2_spectral_product(f, s2_kernel_spectrum(w, grid, lmax))
    return h.reshape(h.shape[:-2] + (-1,))


def s2_correlate(x, w, grid: KernelGrid, b_out: int):
    """S2 signals ``[..., C, 2B_in, 2B_in]`` -> SO(3) ``[..., D, 2B_out, 2B_out, 2B_out]``."""
    return _spectral_correlate(x, w, grid, b_out, on_so3=False)


def so3_correlate(x, w, grid: KernelGrid, b_out: int):
    """SO(3) signals ``[..., C, 2B_in, 2B_in, 2B_in]`` -> ``[..., D, 2B_out, 2B_out, 2B_out]``."""
    return _spectral_correlate(x, w, grid, b_out, on_so3=True)


def _check_band_change(b_in, b_out):
    so3.check_bandwidth(b_out, "b_out")
    if b_out > b_in:
        raise ValueError(f"b_out={b_out} > b_in={b_in}: correlation can only keep or lower "
                         f"the band limit")
