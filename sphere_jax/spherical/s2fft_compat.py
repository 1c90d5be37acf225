"""Our grids and coefficients as s2fft (the JAX spherical-transform library) holds them, so the
two can be checked against each other and timed side by side
(``python -m experiments.bench --suite=peers``, ``tests/spherical/test_s2fft_compat.py``).

What differs, and why the conversion is exact for band-limited signals (``L = B``, s2fft's
Driscoll–Healy sampling ``sampling="dh"``, ``reality=True``, azimuthal band limit ``N = L``):

* **β grid**: the same. s2fft's DH colatitudes ``θ_t = π(2t+1)/4L``, t < 2L, are the SOFT
  ``β_j`` of :mod:`sphere_jax.spherical.so3`.
* **α and γ grids**: ours have ``2B`` samples ``2πk/2B``, s2fft's ``2L−1`` samples
  ``2πp/(2L−1)``. A signal band-limited to ``|m| < L`` is fixed by either set, so we move it
  exactly: FFT over our ``2B`` samples, keep ``|m| ≤ L−1`` (nothing else is there), inverse FFT
  onto ``2L−1`` samples.
* **Axis order on SO(3)**: ours ``[β, α, γ]``, s2fft's ``[γ, β, α]``.
* **S2 coefficients**: the same basis — ``Y^l_m(β, α) = sqrt((2l+1)/4π) d^l_{m0}(β) e^{imα}``
  with Condon–Shortley phase in both — so the same numbers; ours store ``m ≥ 0``, s2fft all
  ``m`` (``[L, 2L−1]``, index ``m + L−1``): the rest from ``f̂^l_{−m} = (−1)^m conj f̂^l_m``.
* **SO(3) coefficients**: the same ``D^l_{mn}(α, β, γ) = e^{−imα} d^l_{mn}(β) e^{−inγ}``, but
  s2fft's ``f^l_{mn} = ∫ f D^l_{mn}`` lacks our ``(2l+1)/8π²``, so theirs are ours × ``8π²/(2l+1)``;
  layout ``[2N−1(n), L, 2L−1(m)]`` against our ``[L, 2L−1(m), L(n ≥ 0)]``, negative ``n`` from
  ``f̂^l_{−m,−n} = (−1)^{m−n} conj f̂^l_{mn}``.

Measured with this conversion at B = 8 (float32): coefficients agree to ~1e-6 relative.
"""
from __future__ import annotations

import numpy as np

KINDS = ("s2_grid", "s2_coeffs", "so3_grid", "so3_coeffs")


def to_s2fft(x, kind):
    """Our array of ``kind`` (:data:`KINDS`; leading axes are batch axes) as s2fft's:

    ``s2_grid [..., 2B, 2B]`` → ``[..., 2B, 2B−1]``; ``s2_coeffs [..., L, L]`` →
    ``[..., L, 2L−1]``; ``so3_grid [..., 2B, 2B, 2B]`` → ``[..., 2B−1, 2B, 2B−1]``;
    ``so3_coeffs [..., L, 2L−1, L]`` → ``[..., 2L−1, L, 2L−1]`` (module docstring).
    """
    x = np.asarray(x)
    if kind == "s2_grid":
        b = x.shape[-1] // 2
        return _resample(x, 2 * b - 1, -1)
    if kind == "so3_grid":
        b = x.shape[-1] // 2
        moved = _resample(_resample(x, 2 * b - 1, -2), 2 * b - 1, -1)
        return np.moveaxis(moved, -1, -3)                          # [β, α, γ] -> [γ, β, α]
    if kind == "s2_coeffs":
        lmax = x.shape[-1]
        m = np.arange(1, lmax)
        neg = ((-1.0) ** m) * np.conj(x[..., :, 1:])               # f̂^l_{-m}, m = 1..L-1
        return np.concatenate([neg[..., ::-1], x], axis=-1)
    if kind == "so3_coeffs":
        lmax = x.shape[-3]
        m = np.arange(-(lmax - 1), lmax)
        n = np.arange(1, lmax)
        # f̂^l_{m,-n} = (-1)^{m+n} conj f̂^l_{-m,n}: flip m, conjugate, sign by (m + n).
        neg = ((-1.0) ** (m[:, None] + n[None, :])) * np.conj(x[..., ::-1, 1:])
        full = np.concatenate([neg[..., ::-1], x], axis=-1)      # [..., L, 2L-1(m), 2L-1(n)]
        scale = 8 * np.pi ** 2 / (2 * np.arange(lmax) + 1)
        full = full * scale[:, None, None]
        return np.moveaxis(full, -1, -3)                          # [..., n, l, m]
    raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")


def _resample(x, n, axis):
    """A real signal band-limited to ``|m| ≤ (n−1)/2`` along ``axis``, from its samples there
    onto ``n`` equispaced samples (exact: only those frequencies are present)."""
    size = x.shape[axis]
    spec = np.moveaxis(np.fft.fft(x, axis=axis), axis, 0)
    k = np.fft.fftfreq(size, 1 / size).astype(int)
    keep = np.abs(k) <= (n - 1) // 2
    out = np.zeros((n,) + spec.shape[1:], complex)
    out[k[keep] % n] = spec[keep]
    return np.moveaxis(np.real(np.fft.ifft(out, axis=0)) * (n / size), 0, axis)
