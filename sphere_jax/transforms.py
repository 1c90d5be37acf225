"""S2 and SO(3) Fourier transforms on SOFT grids, band-limit change and spectral rotation.

Bases (orthonormal on S2; orthogonal on SO(3)), in the Wigner convention of :mod:`wigner`:

* S2:  ``f(β, α) = Σ_{l<L} Σ_m f̂^l_m Y^l_m(β, α)``,
  ``Y^l_m(β, α) = sqrt((2l+1)/4π) d^l_{m0}(β) e^{imα} = sqrt((2l+1)/4π) conj(D^l_{m0}(α, β, 0))``.
* SO(3): ``f(R) = Σ_{l<L} Σ_{mn} f̂^l_{mn} conj(D^l_{mn}(R))``,
  ``f̂^l_{mn} = (2l+1)/(8π²) ∫ f(R) D^l_{mn}(R) dR``.

With these bases rotation is a matrix product on the first index: ``(L_R f)^ = D^l(R) f̂``,
on S2 and on SO(3) alike (``(L_R f)(x) = f(R⁻¹x)``).

Signals are real, so only half of each spectrum is stored (the rest follows from
``f̂^l_{-m} = (-1)^m conj(f̂^l_m)`` and ``f̂^l_{-m,-n} = (-1)^{m-n} conj(f̂^l_{mn})``):

* S2 coefficients:    complex64 ``[..., L(l), L(m ≥ 0), C]``
* SO(3) coefficients: complex64 ``[..., L(l), L(m ≥ 0), 2L-1(n + L-1), C]``

zero where ``m > l`` or ``|n| > l``. Grids are channels last (:mod:`so3`). The forward transforms
take ``lmax=L ≤ B`` and so change band limit by truncation; the inverse transforms take the output
bandwidth ``B ≥ L``. All tables are float64 numpy constants cast to float32, cached per size.
"""
from __future__ import annotations

import functools

import numpy as np
import jax.numpy as jnp

from sphere_jax import so3, wigner


def _check_sizes(b, lmax, name_b="bandwidth"):
    b = so3.check_bandwidth(b, name_b)
    lmax = b if lmax is None else so3.check_bandwidth(lmax, "lmax")
    if lmax > b:
        raise ValueError(f"lmax={lmax} exceeds {name_b}={b}: the grid cannot resolve it")
    return b, lmax


def _check_grid(x, b_axes, name="x"):
    """The grid bandwidth of ``x`` whose ``b_axes`` axes before the channel axis are all 2B."""
    shape = tuple(x.shape)
    if len(shape) < b_axes + 1:
        raise ValueError(f"{name} must have shape [..., {', '.join(['2B'] * b_axes)}, C], "
                         f"got {shape}")
    grid = shape[-1 - b_axes:-1]
    if len(set(grid)) != 1 or grid[0] % 2:
        raise ValueError(f"{name} grid axes must all equal an even 2B, got {grid} in {shape}")
    return grid[0] // 2


# ----------------------------------------------------------------------------------------------
# Tables
# ----------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _s2_tables(b: int, lmax: int):
    """Analysis ``[2B, L, L]`` (quadrature folded in) and synthesis ``[2B, L, L]`` tables."""
    d = wigner.wigner_d_dense(lmax, so3.grid_beta(b))[..., lmax - 1:, lmax - 1]  # [j, l, m≥0]
    norm = np.sqrt((2 * np.arange(lmax) + 1) / (4 * np.pi))[None, :, None]
    synth = norm * d
    analysis = synth * (so3.quadrature_weights(b) * (2 * np.pi / (2 * b)))[:, None, None]
    return analysis.astype(np.float32), synth.astype(np.float32)


@functools.lru_cache(maxsize=None)
def _so3_tables(b: int, lmax: int):
    """Analysis and synthesis tables ``[2B(j), L(l), L(m≥0), 2L-1(n)]``, float32."""
    d = wigner.wigner_d_dense(lmax, so3.grid_beta(b))[:, :, lmax - 1:, :]
    scale = (2 * np.arange(lmax) + 1) / (8 * np.pi ** 2) * (2 * np.pi / (2 * b)) ** 2
    analysis = d * scale[None, :, None, None] * so3.quadrature_weights(b)[:, None, None, None]
    return analysis.astype(np.float32), d.astype(np.float32)


def _complex_contract(spec: str, z, table):
    """einsum of a complex array with a real table, as two real contractions."""
    return jnp.einsum(spec, z.real, table) + 1j * jnp.einsum(spec, z.imag, table)


# ----------------------------------------------------------------------------------------------
# S2
# ----------------------------------------------------------------------------------------------

def s2_fft(x, lmax=None):
    """Real S2 signal ``[..., 2B(β), 2B(α), C]`` -> coefficients ``[..., L, L(m≥0), C]``."""
    b, lmax = _check_sizes(_check_grid(x, 2), lmax)
    analysis, _ = _s2_tables(b, lmax)
    f = jnp.fft.rfft(jnp.asarray(x, jnp.float32), axis=-2)[..., :lmax, :]   # e^{-imα}
    return _complex_contract("...jmc,jlm->...lmc", f, analysis)


def s2_ifft(coeffs, b=None):
    """Coefficients ``[..., L, L, C]`` -> real S2 signal ``[..., 2B, 2B, C]`` (B ≥ L)."""
    lmax = _check_coeffs(coeffs, 2)
    b, lmax = _check_sizes(lmax if b is None else b, lmax)
    _, synth = _s2_tables(b, lmax)
    g = _complex_contract("...lmc,jlm->...jmc", coeffs, synth)
    g = jnp.pad(g, [(0, 0)] * (g.ndim - 2) + [(0, b + 1 - lmax), (0, 0)])
    return jnp.fft.irfft(g, n=2 * b, axis=-2) * (2 * b)


# ----------------------------------------------------------------------------------------------
# SO(3)
# ----------------------------------------------------------------------------------------------

def so3_fft(x, lmax=None):
    """Real SO(3) signal ``[..., 2B(β), 2B(α), 2B(γ), C]`` -> ``[..., L, L(m≥0), 2L-1, C]``."""
    b, lmax = _check_sizes(_check_grid(x, 3), lmax)
    analysis, _ = _so3_tables(b, lmax)
    f = jnp.fft.fft(jnp.fft.rfft(jnp.asarray(x, jnp.float32), axis=-3)[..., :lmax, :, :],
                    axis=-2)
    # FFT bins n mod 2B -> n = -(L-1)..L-1
    f = jnp.concatenate([f[..., 2 * b - lmax + 1:, :], f[..., :lmax, :]], axis=-2)
    return _complex_contract("...jmnc,jlmn->...lmnc", f, analysis)


def so3_ifft(coeffs, b=None):
    """Coefficients ``[..., L, L, 2L-1, C]`` -> real SO(3) signal ``[..., 2B, 2B, 2B, C]``."""
    lmax = _check_coeffs(coeffs, 3)
    b, lmax = _check_sizes(lmax if b is None else b, lmax)
    _, synth = _so3_tables(b, lmax)
    g = _complex_contract("...lmnc,jlmn->...jmnc", coeffs, synth)
    # n = -(L-1)..L-1 -> FFT bins of length 2B: [0..L-1, zeros, -(L-1)..-1]
    zeros = jnp.zeros(g.shape[:-2] + (2 * b - 2 * lmax + 1, g.shape[-1]), g.dtype)
    g = jnp.concatenate([g[..., lmax - 1:, :], zeros, g[..., :lmax - 1, :]], axis=-2)
    g = jnp.fft.ifft(g, axis=-2)
    g = jnp.pad(g, [(0, 0)] * (g.ndim - 3) + [(0, b + 1 - lmax), (0, 0), (0, 0)])
    return jnp.fft.irfft(g, n=2 * b, axis=-3) * (2 * b) ** 2


def _check_coeffs(c, kind_axes):
    shape = tuple(c.shape)
    if kind_axes == 2:
        ok = len(shape) >= 3 and shape[-3] == shape[-2]
        form = "[..., L, L, C]"
    else:
        ok = len(shape) >= 4 and shape[-4] == shape[-3] and shape[-2] == 2 * shape[-3] - 1
        form = "[..., L, L, 2L-1, C]"
    if not ok:
        raise ValueError(f"coeffs must have shape {form}, got {shape}")
    return shape[-1 - kind_axes]


# ----------------------------------------------------------------------------------------------
# Spectral rotation
# ----------------------------------------------------------------------------------------------

def _full_m(coeffs_half, m_axis, n_axis=None):
    """Rebuild m = -(L-1)..L-1 from the stored m ≥ 0 half (real-signal symmetry)."""
    lmax = coeffs_half.shape[m_axis]
    m = np.arange(lmax)
    neg = jnp.conj(jnp.flip(jnp.take(coeffs_half, np.arange(1, lmax), axis=m_axis), m_axis))
    sign_m = (-1.0) ** np.arange(lmax - 1, 0, -1)    # (-1)^m for m = L-1..1
    shape = [1] * coeffs_half.ndim
    shape[m_axis] = lmax - 1
    neg = neg * sign_m.reshape(shape)
    if n_axis is not None:   # f̂_{-m,n} = (-1)^{m-n} conj(f̂_{m,-n}): flip n and sign (-1)^n too
        neg = jnp.flip(neg, n_axis)
        nshape = [1] * coeffs_half.ndim
        nshape[n_axis] = 2 * lmax - 1
        neg = neg * ((-1.0) ** np.arange(-(lmax - 1), lmax)).reshape(nshape)
    del m
    return jnp.concatenate([neg, coeffs_half], axis=m_axis)


def rotate_s2_coeffs(coeffs, rot_33):
    """``(L_R f)^`` for S2 coefficients ``[..., L, L, C]`` and a rotation ``[3, 3]``."""
    lmax = _check_coeffs(coeffs, 2)
    d = wigner.wigner_D_jax(lmax, *so3.matrix_to_euler(rot_33))[:, lmax - 1:, :]  # [l, k≥0, m]
    full = _full_m(coeffs, coeffs.ndim - 2)
    return jnp.einsum("lkm,...lmc->...lkc", d, full)


def rotate_so3_coeffs(coeffs, rot_33):
    """``(L_R f)^`` for SO(3) coefficients ``[..., L, L, 2L-1, C]`` and a rotation ``[3, 3]``."""
    lmax = _check_coeffs(coeffs, 3)
    d = wigner.wigner_D_jax(lmax, *so3.matrix_to_euler(rot_33))[:, lmax - 1:, :]
    full = _full_m(coeffs, coeffs.ndim - 3, coeffs.ndim - 2)
    return jnp.einsum("lkm,...lmnc->...lknc", d, full)


def rotate_s2(x, rot_33):
    """Rotate a band-limited S2 signal ``[..., 2B, 2B, C]``: ``x(R⁻¹ ·)``."""
    b = _check_grid(x, 2)
    return s2_ifft(rotate_s2_coeffs(s2_fft(x), rot_33), b)


def rotate_so3(x, rot_33):
    """Rotate a band-limited SO(3) signal ``[..., 2B, 2B, 2B, C]``: ``x(R⁻¹ ·)``."""
    b = _check_grid(x, 3)
    return so3_ifft(rotate_so3_coeffs(so3_fft(x), rot_33), b)
