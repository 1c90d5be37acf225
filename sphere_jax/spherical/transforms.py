"""S2 and SO(3) Fourier transforms on SOFT grids, band-limit change and spectral rotation.

Bases (orthonormal on S2; orthogonal on SO(3)), in the Wigner convention of :mod:`wigner`:

* S2:  ``f(β, α) = Σ_{l<L} Σ_m f̂^l_m Y^l_m(β, α)``,
  ``Y^l_m(β, α) = sqrt((2l+1)/4π) d^l_{m0}(β) e^{imα} = sqrt((2l+1)/4π) conj(D^l_{m0}(α, β, 0))``.
* SO(3): ``f(R) = Σ_{l<L} Σ_{mn} f̂^l_{mn} conj(D^l_{mn}(R))``,
  ``f̂^l_{mn} = (2l+1)/(8π²) ∫ f(R) D^l_{mn}(R) dR``.

With these bases rotation is a matrix product on the first index: ``(L_R f)^ = D^l(R) f̂``,
on S2 and on SO(3) alike (``(L_R f)(x) = f(R⁻¹x)``).

Signals are real, so half of each spectrum is stored — non-negative frequency on the last grid
axis (α on S2, γ on SO(3)) — and the rest follows from ``f̂^l_{-m} = (-1)^m conj(f̂^l_m)`` and
``f̂^l_{-m,-n} = (-1)^{m-n} conj(f̂^l_{mn})``:

* S2 coefficients:    complex64 ``[..., L(l), L(m ≥ 0)]``
* SO(3) coefficients: complex64 ``[..., L(l), 2L-1(m + L-1), L(n ≥ 0)]``

zero where ``|m| > l`` or ``n > l``. Grids are channels first (:mod:`so3`); every leading axis
(batch, channel) is a batch axis here. The forward transforms take ``lmax=L ≤ B`` and so change
band limit by truncation; the inverse transforms take the output bandwidth ``B ≥ L``.
All tables are float64 numpy constants cast to float32, cached per size. The layers use the
real-arithmetic ``*_analysis`` / ``*_synthesis`` functions and their internal layouts directly;
the complex functions are the interface for users and tests.
"""
from __future__ import annotations

import functools

import numpy as np
import jax
import jax.numpy as jnp

from sphere_jax.spherical import so3, wigner


def check_sizes(b, lmax, name_b="bandwidth"):
    """Validated ``(B, L)``; ``L`` defaults to ``B`` and may not exceed it."""
    b = so3.check_bandwidth(b, name_b)
    lmax = b if lmax is None else so3.check_bandwidth(lmax, "lmax")
    if lmax > b:
        raise ValueError(f"lmax={lmax} exceeds {name_b}={b}: the grid cannot resolve it")
    return b, lmax


def grid_bandwidth(x, grid_ndim, name="x"):
    """Bandwidth B of ``x`` whose last ``grid_ndim`` axes must all be an even 2B."""
    shape = tuple(x.shape)
    form = ", ".join(["2B"] * grid_ndim)
    if len(shape) < grid_ndim:
        raise ValueError(f"{name} must have shape [..., {form}], got {shape}")
    grid = shape[-grid_ndim:]
    if len(set(grid)) != 1 or grid[0] % 2 or grid[0] == 0:
        raise ValueError(f"{name} grid axes must all equal an even 2B > 0, got {grid} "
                         f"in shape {shape} (expected [..., {form}])")
    return grid[0] // 2


def coeffs_lmax(c, on_so3, name="coeffs"):
    """Band limit L of an S2 ``[..., L, L]`` or SO(3) ``[..., L, 2L-1, L]`` coefficient array."""
    s = tuple(c.shape)
    if on_so3:
        ok = len(s) >= 3 and s[-3] == s[-1] and s[-2] == 2 * s[-1] - 1
        form = "[..., L, 2L-1, L]"
    else:
        ok = len(s) >= 2 and s[-2] == s[-1]
        form = "[..., L, L]"
    if not ok or s[-1] == 0:
        raise ValueError(f"{name} must have shape {form}, got {s}")
    return s[-1]


# ----------------------------------------------------------------------------------------------
# Tables (float64 numpy, cast to float32, cached per size)
#
# The transforms run on real arrays with an explicit (re, im) axis: XLA on CPU moves and
# multiplies complex64 arrays several times slower than float32 ones (measured: a transpose of
# 20 MB is 2.4 ms real, 25 ms complex). The α and γ DFTs are GEMMs against these tables rather
# than FFTs: they produce only the 2L-1 (or L) frequencies needed, in the layout the next step
# wants, at GEMM speed.
# ----------------------------------------------------------------------------------------------

def _trig(freqs, b):
    angle = np.outer(so3.grid_alpha(b), freqs)                        # [2B, F]
    return np.cos(angle), np.sin(angle)


def table_f32(t):
    """A float64 table as contiguous float32 (tables are built in float64, used in float32)."""
    return np.ascontiguousarray(t).astype(np.float32)


@functools.lru_cache(maxsize=None)
def forward_dft(b: int, n_freq: int, full: bool):
    """``Σ_a e^{-ifα_a}`` as real tables. ``full=False``: real input, f ∈ [0, n) ->
    ``[2B(a), 2(re/im), n]``. ``full=True``: complex input (re/im axis r), f ∈ (-n, n) ->
    ``[2B(a), 2(r), 2(re/im out), 2n-1]``."""
    if not full:
        c, s = _trig(np.arange(n_freq), b)
        return table_f32(np.stack([c, -s], 1))
    c, s = _trig(np.arange(-(n_freq - 1), n_freq), b)
    # (x_re + i x_im)(cos - i sin) = (x_re cos + x_im sin) + i(x_im cos - x_re sin)
    return table_f32(np.stack([np.stack([c, -s], 1), np.stack([s, c], 1)], 1))


@functools.lru_cache(maxsize=None)
def inverse_dft(b: int, n_freq: int, full: bool):
    """``Σ_f e^{ifα_a}``. ``full=False``: half spectrum f ∈ [0, n) of a real signal ->
    ``[n, 2(r), 2B(a)]`` giving ``Σ_f w_f Re(x_f e^{ifα})`` with w_0 = 1, w_f = 2 (the
    conjugate half). ``full=True``: f ∈ (-n, n) -> ``[2n-1, 2(r), 2B(a), 2(re/im out)]``."""
    if not full:
        c, s = _trig(np.arange(n_freq), b)
        w = np.where(np.arange(n_freq) == 0, 1.0, 2.0)
        return table_f32(np.stack([c.T * w[:, None], -s.T * w[:, None]], 1))
    c, s = _trig(np.arange(-(n_freq - 1), n_freq), b)
    # (x_re + i x_im)(cos + i sin) = (x_re cos - x_im sin) + i(x_re sin + x_im cos)
    return table_f32(np.stack([np.stack([c.T, s.T], -1), np.stack([-s.T, c.T], -1)], 1))


@functools.lru_cache(maxsize=None)
def s2_tables(b: int, lmax: int):
    """Wigner-d tables ``[L(m≥0), L(l), 2B(j)]`` for analysis (carrying the quadrature weights
    and the α step 2π/2B) and synthesis."""
    d = wigner.wigner_d_dense(lmax, so3.grid_beta(b))[..., lmax - 1:, lmax - 1]  # [j, l, m≥0]
    synth = d * np.sqrt((2 * np.arange(lmax) + 1) / (4 * np.pi))[None, :, None]
    analysis = synth * (so3.quadrature_weights(b) * (2 * np.pi / (2 * b)))[:, None, None]
    return table_f32(analysis.transpose(2, 1, 0)), table_f32(synth.transpose(2, 1, 0))


@functools.lru_cache(maxsize=None)
def so3_tables(b: int, lmax: int):
    """Wigner-d tables ``[2L-1(m), L(n≥0), L(l), 2B(j)]`` for analysis and synthesis."""
    d = wigner.wigner_d_dense(lmax, so3.grid_beta(b))[..., lmax - 1:]          # [j, l, m, n≥0]
    scale = (2 * np.arange(lmax) + 1) / (8 * np.pi ** 2) * (2 * np.pi / (2 * b)) ** 2
    analysis = d * scale[None, :, None, None] * so3.quadrature_weights(b)[:, None, None, None]
    return table_f32(analysis.transpose(2, 3, 1, 0)), table_f32(d.transpose(2, 3, 1, 0))


# ----------------------------------------------------------------------------------------------
# Real-arithmetic transforms in the internal spectral layouts
#
#   S2 spectrum     [L(m≥0), L(l), 2(re/im), X]
#   SO(3) spectrum  [2L-1(m), L(n≥0), L(l), 2(re/im), X]
#
# X is every leading axis of the signal (batch × channels) flattened, kept minor so that the
# Wigner-d step is a matmul batched over (m, n) with long contiguous rows, and so that the
# per-degree slices the correlations take are contiguous blocks. The einsum output orders of
# the intermediate steps were picked by timing the variants (B=16, X=320): XLA inserts the
# transposes, and these orders make the cheapest ones.
# ----------------------------------------------------------------------------------------------

def _layout(x, name, form, ok):
    """A trace-time check of an internal layout: a wrong one would fail deep in an einsum."""
    if not ok(tuple(x.shape)):
        raise ValueError(f"{name} must have shape {form}; got {tuple(x.shape)}")


def s2_analysis(x_XxJxA, lmax: int):
    """Real S2 signals ``[X, 2B, 2B]`` -> spectrum ``[L, L, 2, X]`` (layout above)."""
    _layout(x_XxJxA, "x_XxJxA", "[X, 2B, 2B]", lambda s: len(s) == 3)
    b, lmax = check_sizes(grid_bandwidth(x_XxJxA, 2, "x_XxJxA"), lmax)
    y = jnp.einsum("xja,arm->mjrx", x_XxJxA, forward_dft(b, lmax, False))
    return jnp.einsum("mjrx,mlj->mlrx", y, s2_tables(b, lmax)[0])


def s2_synthesis(h_MxLx2xX, b: int):
    """Spectrum ``[L, L, 2, X]`` -> real S2 signals ``[X, 2B, 2B]``."""
    _layout(h_MxLx2xX, "h_MxLx2xX", "[L, L, 2, X]",
            lambda s: len(s) == 4 and s[0] == s[1] and s[2] == 2)
    b, lmax = check_sizes(b, h_MxLx2xX.shape[0])
    g = jnp.einsum("mlrx,mlj->mjrx", h_MxLx2xX, s2_tables(b, lmax)[1])
    return jnp.einsum("mjrx,mra->xja", g, inverse_dft(b, lmax, False))


def so3_analysis(x_XxJxAxG, lmax: int):
    """Real SO(3) signals ``[X, 2B, 2B, 2B]`` -> spectrum ``[2L-1, L, L, 2, X]``."""
    _layout(x_XxJxAxG, "x_XxJxAxG", "[X, 2B, 2B, 2B]", lambda s: len(s) == 4)
    b, lmax = check_sizes(grid_bandwidth(x_XxJxAxG, 3, "x_XxJxAxG"), lmax)
    y = jnp.einsum("xjag,grn->xjarn", x_XxJxAxG, forward_dft(b, lmax, False))    # γ
    y = jnp.einsum("xjarn,arsm->smnxj", y, forward_dft(b, lmax, True))           # α
    return jnp.einsum("smnxj,mnlj->mnlsx", y, so3_tables(b, lmax)[0])            # β


def so3_synthesis(h_MxNxLx2xX, b: int):
    """Spectrum ``[2L-1, L, L, 2, X]`` -> real SO(3) signals ``[X, 2B, 2B, 2B]``."""
    _layout(h_MxNxLx2xX, "h_MxNxLx2xX", "[2L-1, L, L, 2, X]",
            lambda s: len(s) == 5 and s[0] == 2 * s[1] - 1 and s[1] == s[2] and s[3] == 2)
    b, lmax = check_sizes(b, h_MxNxLx2xX.shape[1])
    g = jnp.einsum("mnlsx,mnlj->mnsxj", h_MxNxLx2xX, so3_tables(b, lmax)[1])     # β
    g = jnp.einsum("mnsxj,msar->nxjar", g, inverse_dft(b, lmax, True))           # α
    return jnp.einsum("nxjar,nrg->xjag", g, inverse_dft(b, lmax, False))         # γ


# ----------------------------------------------------------------------------------------------
# Complex coefficients (the public interface)
# ----------------------------------------------------------------------------------------------

def _to_complex(s, perm):
    """Internal real spectrum -> complex ``[X, ...]``: ``perm`` puts X first and re/im last."""
    return jax.lax.complex(*jnp.moveaxis(jnp.transpose(s, perm), -1, 0))


def _to_real(c, perm):
    """Complex ``[X, ..., ]`` -> internal real spectrum: ``perm`` of ``[X, ..., re/im]``."""
    c = jnp.asarray(c, jnp.complex64)
    return jnp.transpose(jnp.stack([c.real, c.imag], -1), perm)


def s2_fft(x, lmax=None):
    """Real S2 signal ``[..., 2B(β), 2B(α)]`` -> coefficients ``[..., L, L(m≥0)]``."""
    b, lmax = check_sizes(grid_bandwidth(x, 2), lmax)
    lead = x.shape[:-2]
    s = s2_analysis(jnp.asarray(x, jnp.float32).reshape((-1, 2 * b, 2 * b)), lmax)
    return _to_complex(s, (3, 1, 0, 2)).reshape(lead + (lmax, lmax))


def s2_ifft(coeffs, b=None):
    """Coefficients ``[..., L, L]`` -> real S2 signal ``[..., 2B, 2B]`` (B ≥ L, default L)."""
    lmax = coeffs_lmax(coeffs, False)
    b, lmax = check_sizes(lmax if b is None else b, lmax)
    lead = coeffs.shape[:-2]
    h = _to_real(jnp.reshape(coeffs, (-1, lmax, lmax)), (2, 1, 3, 0))
    return s2_synthesis(h, b).reshape(lead + (2 * b, 2 * b))


def so3_fft(x, lmax=None):
    """Real SO(3) signal ``[..., 2B(β), 2B(α), 2B(γ)]`` -> ``[..., L, 2L-1(m), L(n≥0)]``."""
    b, lmax = check_sizes(grid_bandwidth(x, 3), lmax)
    lead = x.shape[:-3]
    s = so3_analysis(jnp.asarray(x, jnp.float32).reshape((-1,) + (2 * b,) * 3), lmax)
    return _to_complex(s, (4, 2, 0, 1, 3)).reshape(lead + (lmax, 2 * lmax - 1, lmax))


def so3_ifft(coeffs, b=None):
    """Coefficients ``[..., L, 2L-1, L]`` -> real SO(3) signal ``[..., 2B, 2B, 2B]`` (B ≥ L)."""
    lmax = coeffs_lmax(coeffs, True)
    b, lmax = check_sizes(lmax if b is None else b, lmax)
    lead = coeffs.shape[:-3]
    h = _to_real(jnp.reshape(coeffs, (-1, lmax, 2 * lmax - 1, lmax)), (2, 3, 1, 4, 0))
    return so3_synthesis(h, b).reshape(lead + (2 * b,) * 3)


# ----------------------------------------------------------------------------------------------
# Real-signal symmetry and spectral rotation
# ----------------------------------------------------------------------------------------------

def s2_full_m(c):
    """S2 half spectrum ``[..., L, L(m≥0)]`` -> full ``[..., L, 2L-1(m + L-1)]``."""
    lmax = c.shape[-1]
    sign = (-1.0) ** np.arange(lmax - 1, 0, -1)                       # (-1)^m, m = L-1..1
    neg = jnp.conj(jnp.flip(c[..., 1:], -1)) * sign
    return jnp.concatenate([neg, c], axis=-1)


def _wigner_D_at(lmax, rot_33):
    rot_33 = so3.check_rotation(rot_33)
    return wigner.wigner_D_jax(lmax, *so3.matrix_to_euler(rot_33))   # [l, m, m']


def rotate_s2_coeffs(coeffs, rot_33):
    """``(L_R f)^ = D(R) f̂`` for S2 coefficients ``[..., L, L]`` and a rotation ``[3, 3]``."""
    lmax = coeffs_lmax(coeffs, False)
    d = _wigner_D_at(lmax, rot_33)[:, lmax - 1:, :]                  # [l, k≥0, m]
    return jnp.einsum("lkm,...lm->...lk", d, s2_full_m(coeffs))


def rotate_so3_coeffs(coeffs, rot_33):
    """``(L_R f)^ = D(R) f̂`` for SO(3) coefficients ``[..., L, 2L-1, L]``, rotation ``[3, 3]``."""
    lmax = coeffs_lmax(coeffs, True)
    return jnp.einsum("lkm,...lmn->...lkn", _wigner_D_at(lmax, rot_33), coeffs)


def rotate_s2(x, rot_33):
    """Rotate a band-limited S2 signal ``[..., 2B, 2B]``: returns ``x(R⁻¹ ·)``."""
    return s2_ifft(rotate_s2_coeffs(s2_fft(x), rot_33), grid_bandwidth(x, 2))


def rotate_so3(x, rot_33):
    """Rotate a band-limited SO(3) signal ``[..., 2B, 2B, 2B]``: returns ``x(R⁻¹ ·)``."""
    return so3_ifft(rotate_so3_coeffs(so3_fft(x), rot_33), grid_bandwidth(x, 3))


def so3_moments(h_MxNxLx2xX):
    """Haar mean and mean square ``([X], [X])`` of the real SO(3) signals whose internal
    spectra are ``h`` — exact, with no grid. ``f = Σ f̂^l_{mn} conj(D^l_{mn})`` and
    ``∫ D^l_{mn} conj(D^l'_{m'n'}) dR / 8π² = δ / (2l+1)`` make the mean the degree-0
    coefficient and the mean square ``Σ_l Σ_{mn} |f̂^l_{mn}|² / (2l+1)`` (Parseval); the stored
    half n ≥ 0 counts twice for n > 0 (``|f̂_{-m,-n}| = |f̂_{mn}|``)."""
    lmax = h_MxNxLx2xX.shape[1]
    n, l = np.arange(lmax), np.arange(lmax)
    w = np.where(n == 0, 1.0, 2.0)[:, None] / (2 * l + 1)[None, :]         # [n, l]
    w = jnp.asarray(w, jnp.float32)
    mean = h_MxNxLx2xX[lmax - 1, 0, 0, 0]
    mean_sq = jnp.einsum("mnlrx,nl->x", jnp.square(h_MxNxLx2xX), w)
    return mean, mean_sq


def so3_grid_moments(x):
    """Haar mean and mean square ``([...], [...])`` of SO(3) signals ``[..., 2B, 2B, 2B]`` by
    the SOFT quadrature: exact for band-B signals, so they equal :func:`so3_moments` of their
    spectra (the quadrature integrates products of two band-B functions exactly)."""
    b = grid_bandwidth(x, 3)
    w = jnp.asarray(so3.haar_weights(b), jnp.float32)
    return jnp.einsum("...jag,j->...", x, w), jnp.einsum("...jag,j->...", jnp.square(x), w)


def so3_haar_mean(x):
    """Haar mean ``[...]`` of SO(3) signals ``[..., 2B, 2B, 2B]``: exact for band-B signals and
    invariant under rotation of the signal (the invariant pooling of the spherical CNNs)."""
    b = grid_bandwidth(x, 3)
    w = jnp.asarray(so3.haar_weights(b), jnp.float32)
    return jnp.einsum("...jag,j->...", x, w)
