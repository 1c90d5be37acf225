"""Wigner-d and Wigner-D functions, built once in float64.

Convention (s2cnn / lie_learn, CONVENTIONS.md §4):
``D^l_{mn}(α, β, γ) = e^{-imα} d^l_{mn}(β) e^{-inγ}``, with ``d^l(β) = exp(-iβ J_y)`` in the
basis ``|l, m⟩`` (Condon–Shortley phases). D is a representation:
``D(R1 R2) = D(R1) D(R2)`` for ``R = Rz(α) Ry(β) Rz(γ)``.

Stability: ``J_y`` has the integer eigenvalues ``λ = -l..l``, so ``d^l_{mn}(β)`` is the exact
trigonometric polynomial ``Σ_λ C^l_{mnλ} e^{-iλβ}`` with ``C^l_{mnλ} = V_{mλ} V*_{nλ}`` from one
Hermitian eigendecomposition per degree. No recursion, no factorials: float64 accuracy ~1e-13 at
l = 100. The same coefficients evaluate ``d(β)`` for a *traced* β in JAX (spectral rotation).

Layouts: index m or n = -l..l is stored at ``m + l`` in per-degree arrays and at ``m + L - 1`` in
dense arrays over all degrees ``l < L``, zero where ``|m| > l``.
"""
from __future__ import annotations

import functools

import numpy as np
import jax.numpy as jnp


@functools.lru_cache(maxsize=None)
def _jy_eigvecs(l: int) -> np.ndarray:
    """Eigenvectors ``V[m + l, λ + l]`` of J_y on degree l (complex128), eigenvalues -l..l."""
    m = np.arange(-l, l)
    jplus = np.zeros((2 * l + 1, 2 * l + 1))
    # ⟨m+1| J+ |m⟩ = sqrt(l(l+1) - m(m+1))
    jplus[np.arange(1, 2 * l + 1), np.arange(2 * l)] = np.sqrt(l * (l + 1) - m * (m + 1))
    jy = (jplus - jplus.T) / 2j
    lam, vec = np.linalg.eigh(jy)
    assert np.allclose(lam, np.arange(-l, l + 1), atol=1e-8), lam
    return vec


@functools.lru_cache(maxsize=None)
def fourier_coefficients(l: int) -> np.ndarray:
    """``C[m + l, n + l, λ + l]`` (complex128) with ``d^l_{mn}(β) = Re Σ_λ C e^{-iλβ}``."""
    v = _jy_eigvecs(l)
    return np.einsum("ml,nl->mnl", v, v.conj())


def wigner_d(l: int, beta) -> np.ndarray:
    """Wigner small-d ``d^l(β)``: float64 ``[..., 2l+1, 2l+1]`` indexed ``[m + l, n + l]``."""
    if l < 0:
        raise ValueError(f"degree l must be >= 0, got {l}")
    beta = np.asarray(beta, np.float64)
    phase = np.exp(-1j * np.arange(-l, l + 1) * beta[..., None])
    return np.einsum("mnk,...k->...mn", fourier_coefficients(l), phase).real


def wigner_D(l: int, alpha, beta, gamma) -> np.ndarray:
    """Wigner ``D^l(α, β, γ)``: complex128 ``[..., 2l+1, 2l+1]`` indexed ``[m + l, n + l]``."""
    m = np.arange(-l, l + 1)
    alpha, gamma = np.asarray(alpha, np.float64), np.asarray(gamma, np.float64)
    return (np.exp(-1j * m * alpha[..., None])[..., :, None] * wigner_d(l, beta)
            * np.exp(-1j * m * gamma[..., None])[..., None, :])


def wigner_d_dense(lmax: int, beta) -> np.ndarray:
    """All degrees ``l < lmax`` at once: float64 ``[..., L, 2L-1, 2L-1]`` (l, m + L-1, n + L-1)."""
    beta = np.asarray(beta, np.float64)
    out = np.zeros(beta.shape + (lmax, 2 * lmax - 1, 2 * lmax - 1))
    for l in range(lmax):
        s = slice(lmax - 1 - l, lmax + l)
        out[..., l, s, s] = wigner_d(l, beta)
    return out


@functools.lru_cache(maxsize=None)
def _dense_fourier(lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """Real and imaginary parts of C for all l < lmax, ``[L, 2L-1, 2L-1, 2L-1(λ)]``, float32."""
    c = np.zeros((lmax, 2 * lmax - 1, 2 * lmax - 1, 2 * lmax - 1), np.complex128)
    for l in range(lmax):
        s = slice(lmax - 1 - l, lmax + l)
        c[l, s, s, s] = fourier_coefficients(l)
    return c.real.astype(np.float32), c.imag.astype(np.float32)


def wigner_d_jax(lmax: int, beta):
    """``d^l(β)`` for a traced β ``[...]`` (jit/grad-able): float32 ``[..., L, 2L-1, 2L-1]``."""
    cre, cim = _dense_fourier(lmax)
    lam = jnp.arange(-(lmax - 1), lmax, dtype=jnp.float32)
    angle = lam * jnp.asarray(beta, jnp.float32)[..., None]
    # Re(C e^{-iλβ}) = Re C cos λβ + Im C sin λβ
    return (jnp.einsum("lmnk,...k->...lmn", cre, jnp.cos(angle))
            + jnp.einsum("lmnk,...k->...lmn", cim, jnp.sin(angle)))


def wigner_D_jax(lmax: int, alpha, beta, gamma):
    """Dense ``D^l(α, β, γ)`` for traced angles ``[...]``: complex64 ``[..., L, 2L-1, 2L-1]``."""
    m = jnp.arange(-(lmax - 1), lmax, dtype=jnp.float32)
    ea = jnp.exp(-1j * m * jnp.asarray(alpha, jnp.float32)[..., None])
    eg = jnp.exp(-1j * m * jnp.asarray(gamma, jnp.float32)[..., None])
    d = wigner_d_jax(lmax, beta)
    return ea[..., None, :, None] * d * eg[..., None, None, :]

