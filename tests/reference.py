"""Slow, direct NumPy references (float64) that the fast JAX code is compared against.

Everything here is written from the definitions, independently of the tables and FFTs under
test: Wigner's closed-form sum for d, and synthesis / correlation as explicit sums.
"""
from __future__ import annotations

import functools
from math import cos, factorial, sin, sqrt

import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax.spherical import so3, wigner


def wigner_d_explicit(l: int, m: int, n: int, beta: float) -> float:
    """Wigner's closed-form sum for ``d^l_{mn}(β)`` (cancellation-prone for large l)."""
    total = 0.0
    for s in range(max(0, n - m), min(l + n, l - m) + 1):
        total += ((-1) ** (m - n + s) * cos(beta / 2) ** (2 * l + n - m - 2 * s)
                  * sin(beta / 2) ** (m - n + 2 * s)
                  / (factorial(l + n - s) * factorial(s) * factorial(m - n + s)
                     * factorial(l - m - s)))
    return sqrt(factorial(l + m) * factorial(l - m) * factorial(l + n) * factorial(l - n)) * total


def wigner_d_explicit_table(lmax: int, betas) -> np.ndarray:
    """``[len(betas), L, 2L-1, 2L-1]`` from the closed form."""
    betas = np.asarray(betas, np.float64)
    out = np.zeros((len(betas), lmax, 2 * lmax - 1, 2 * lmax - 1))
    for i, b in enumerate(betas):
        for l in range(lmax):
            for m in range(-l, l + 1):
                for n in range(-l, l + 1):
                    out[i, l, m + lmax - 1, n + lmax - 1] = wigner_d_explicit(l, m, n, b)
    return out


def rel_err(a, b):
    """Relative L2 error of ``a`` against the reference ``b``."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# ---- random band-limited coefficients of real signals (half spectra, as transforms stores) --

def random_s2_coeffs(rng, lead, lmax):
    c = rng.normal(size=lead + (lmax, lmax)) + 1j * rng.normal(size=lead + (lmax, lmax))
    c[..., 0] = c[..., 0].real                                     # f̂_{l0} is real
    l, m = np.arange(lmax)[:, None], np.arange(lmax)[None, :]
    return c * (m <= l)


def random_so3_coeffs(rng, lead, lmax):
    shape = lead + (lmax, 2 * lmax - 1, lmax)
    c = rng.normal(size=shape) + 1j * rng.normal(size=shape)
    m = np.arange(-(lmax - 1), lmax)
    # n = 0 column: f̂_{-m,0} = (-1)^m conj(f̂_{m,0}), so f̂_{00} is real.
    pos = c[..., lmax - 1:, 0]
    c[..., :lmax - 1, 0] = (np.conj(pos[..., 1:]) * (-1.0) ** m[lmax:])[..., ::-1]
    c[..., lmax - 1, 0] = c[..., lmax - 1, 0].real
    l = np.arange(lmax)[:, None, None]
    n = np.arange(lmax)[None, None, :]
    return c * ((np.abs(m)[None, :, None] <= l) & (n <= l))


def full_s2(c):
    """Half -> full ``[..., L, 2L-1]`` by ``f̂_{-m} = (-1)^m conj f̂_m``."""
    lmax = c.shape[-1]
    out = np.zeros(c.shape[:-1] + (2 * lmax - 1,), complex)
    for m in range(lmax):
        out[..., lmax - 1 + m] = c[..., m]
        out[..., lmax - 1 - m] = (-1) ** m * np.conj(c[..., m])
    return out


def full_so3(c):
    """Half -> full ``[..., L, 2L-1, 2L-1]`` by ``f̂_{-m,-n} = (-1)^{m-n} conj f̂_{mn}``."""
    lmax = c.shape[-1]
    out = np.zeros(c.shape[:-1] + (2 * lmax - 1,), complex)
    out[..., lmax - 1:] = c
    for m in range(-(lmax - 1), lmax):
        for n in range(1, lmax):
            out[..., lmax - 1 - m, lmax - 1 - n] = (-1) ** (m - n) * np.conj(
                c[..., lmax - 1 + m, n])
    return out


# ---- direct synthesis at arbitrary points ----------------------------------------------------

def s2_eval(c, beta, alpha):
    """``f(β, α) = Σ f̂^l_m Y^l_m`` at points ``[P]``: returns ``[..., P]`` (real)."""
    lmax = c.shape[-1]
    full = full_s2(np.asarray(c, complex))
    d = wigner.wigner_d_dense(lmax, beta)[..., lmax - 1]                 # [P, l, m] = d_{m0}
    m = np.arange(-(lmax - 1), lmax)
    y = d * np.sqrt((2 * np.arange(lmax) + 1) / (4 * np.pi))[:, None] * np.exp(
        1j * m * np.asarray(alpha)[:, None, None])
    return np.einsum("...lm,plm->...p", full, y).real


def so3_eval(c, alpha, beta, gamma):
    """``f(R) = Σ f̂^l_{mn} conj D^l_{mn}(R)`` at rotations ``[P]``: returns ``[..., P]``."""
    lmax = c.shape[-1]
    full = full_so3(np.asarray(c, complex))
    dd = np.zeros((len(alpha), lmax, 2 * lmax - 1, 2 * lmax - 1), complex)
    for l in range(lmax):
        s = slice(lmax - 1 - l, lmax + l)
        dd[:, l, s, s] = wigner.wigner_D(l, alpha, beta, gamma)
    return np.einsum("...lmn,plmn->...p", full, dd.conj()).real


def s2_synth_grid(c, b, d_table=None):
    """Direct synthesis on the 2B×2B grid using closed-form d (or a given table)."""
    lmax = c.shape[-1]
    beta, alpha = so3.s2_grid(b)
    if d_table is None:
        d_table = wigner_d_explicit_table(lmax, so3.grid_beta(b))
    full = full_s2(np.asarray(c, complex))
    m = np.arange(-(lmax - 1), lmax)
    norm = np.sqrt((2 * np.arange(lmax) + 1) / (4 * np.pi))
    y = (d_table[:, :, :, lmax - 1] * norm[:, None])[:, None] * np.exp(
        1j * m * so3.grid_alpha(b)[:, None, None])[None]                # [j, a, l, m]
    return np.einsum("...lm,jalm->...ja", full, y).real


def so3_synth_grid(c, b, d_table=None):
    """Direct synthesis on the 2B×2B×2B grid with closed-form d."""
    lmax = c.shape[-1]
    if d_table is None:
        d_table = wigner_d_explicit_table(lmax, so3.grid_beta(b))
    full = full_so3(np.asarray(c, complex))
    m = np.arange(-(lmax - 1), lmax)
    e = np.exp(1j * m[None, :] * so3.grid_alpha(b)[:, None])           # conj(e^{-imα})
    return np.einsum("...lmn,jlmn,am,gn->...jag", full, d_table, e, e, optimize=True).real


# ---- direct correlation ----------------------------------------------------------------------

def correlate_direct(eval_fn, c_in, w, grid, b_out):
    """``h_d(R) = Σ_{g, c} w[g, c, d] f_c(R g)`` on the output SO(3) grid, by direct evaluation.

    ``eval_fn(c, rotations [P, 3, 3]) -> [..., P]`` evaluates the input signal; c_in is
    ``[C, ...]`` coefficients, w is ``[*grid.shape, C, D]``.
    """
    out_rot = so3.so3_grid_matrices(b_out).reshape(-1, 3, 3)           # [Q, 3, 3]
    g_rot = so3.euler_to_matrix_np(*(a.ravel() for a in grid.points()))  # [G, 3, 3]
    rot = np.einsum("qij,gjk->qgik", out_rot, g_rot).reshape(-1, 3, 3)
    vals = eval_fn(c_in, rot).reshape(c_in.shape[0], len(out_rot), len(g_rot))  # [C, Q, G]
    h = np.einsum("cqg,gcd->dq", vals, w.reshape(len(g_rot), *w.shape[-2:]))
    return h.reshape((-1,) + (2 * b_out,) * 3)


def s2_eval_rot(c, rot):
    """Evaluate S2 coefficients at the points ``R ẑ``."""
    z = rot[:, :, 2]
    beta = np.arccos(np.clip(z[:, 2], -1, 1))
    alpha = np.arctan2(z[:, 1], z[:, 0])
    return s2_eval(c, beta, alpha)


def so3_eval_rot(c, rot):
    return so3_eval(c, *(np.asarray(a) for a in _matrix_to_euler_np(rot)))


def _matrix_to_euler_np(rot):
    beta = np.arccos(np.clip(rot[:, 2, 2], -1, 1))
    alpha = np.arctan2(rot[:, 1, 2], rot[:, 0, 2])
    gamma = np.arctan2(rot[:, 2, 1], -rot[:, 2, 0])
    # Near the poles only α ± γ is defined; take γ = 0.
    pole = np.abs(np.sin(beta)) < 1e-9
    sign = np.where(rot[:, 2, 2] > 0, 1.0, -1.0)                      # β = 0 or β = π
    alpha = np.where(pole, np.arctan2(sign * rot[:, 1, 0], sign * rot[:, 0, 0]), alpha)
    gamma = np.where(pole, 0.0, gamma)
    return alpha, beta, gamma


# ----------------------------------------------------------------------------------------------
# Hand-crafted LRFs and descriptors, one keypoint at a time, written from the papers
# ----------------------------------------------------------------------------------------------

def _neighbours(points, centre, radius):
    d = points - centre
    r = np.linalg.norm(d, axis=1)
    keep = (r <= radius) & (r > 0)
    return d[keep], r[keep], np.nonzero(keep)[0]


def _sign_by_majority(axis, d):
    proj = d @ axis
    votes = np.sum(proj >= 0) - np.sum(proj < 0)
    if votes == 0:
        votes = np.sum(proj)
    return axis if votes >= 0 else -axis


def shot_lrf_loop(points, centre, radius):
    d, r, _ = _neighbours(points, centre, radius)
    cov = sum((radius - ri) * np.outer(di, di) for di, ri in zip(d, r)) / np.sum(radius - r)
    _, vecs = np.linalg.eigh(cov)
    x = _sign_by_majority(vecs[:, 2], d)
    z = _sign_by_majority(vecs[:, 0], d)
    return np.stack([x, np.cross(z, x), z], 1)


def _toldi_frame(d, r, z, radius):
    """ẑ turned so the neighbours lie below it; x̂ the tangent offsets weighted by
    ((R − r)·h)², as TOLDI (and 3DSmoothNet) define it."""
    if np.sum(d @ z) > 0:
        z = -z
    x = np.zeros(3)
    for di, ri in zip(d, r):
        h = di @ z
        x += ((radius - ri) * h) ** 2 * (di - h * z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], 1)


def toldi_lrf_loop(points, centre, radius):
    d, r, _ = _neighbours(points, centre, radius)
    inner = d[r <= radius / 3]
    c = inner - inner.mean(0)
    _, vecs = np.linalg.eigh(c.T @ c)
    return _toldi_frame(d, r, vecs[:, 0], radius)


def threedsn_lrf_loop(points, centre, radius):
    """3DSmoothNet's frame: ẑ from the scatter of the whole support about the keypoint."""
    d, r, _ = _neighbours(points, centre, radius)
    _, vecs = np.linalg.eigh(d.T @ d)
    return _toldi_frame(d, r, vecs[:, 0], radius)


def gframes_lrf_loop(points, normals, centre, radius):
    """GFrames on points: TOLDI's ẑ; x̂ the gradient of the normal deviation 1 − |n·ẑ|, a
    plane fitted by weighted least squares in the tangent plane (spanned by the projections
    of two fixed axes)."""
    d, r, idx = _neighbours(points, centre, radius)
    inner = d[r <= radius / 3]
    c = inner - inner.mean(0)
    z = np.linalg.eigh(c.T @ c)[1][:, 0]
    if np.sum(d @ z) > 0:
        z = -z
    tangent = np.eye(3) - np.outer(z, z)
    u = tangent @ [0.3, 0.5, 0.7]
    u /= np.linalg.norm(u)
    v = np.cross(z, u)
    a = np.array([[1.0, di @ u, di @ v] for di in d])
    f = np.array([1 - abs(normals[k] @ z) for k in idx])
    w = np.sqrt(radius - r)
    coef = np.linalg.lstsq(a * w[:, None], f * w, rcond=None)[0]
    x = coef[1] * u + coef[2] * v
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], 1)


def usc_loop(points, centre, radius, frame, radial=10, elevation=14, azimuth=14):
    """USC of one keypoint as PCL computes it: log-spaced shells from R/10, equal-angle
    elevation and azimuth bins, votes 1 / (density within R/5 · cube root of bin volume)."""
    d, r, idx = _neighbours(points, centre, radius)
    shells = [np.exp(np.log(0.1 * radius) + j / radial * np.log(10.0)) for j in range(radial + 1)]
    hist = np.zeros((azimuth, elevation, radial))
    for di, ri, k in zip(d, r, idx):
        x, y, z = frame.T @ di
        j = next((n for n in range(radial) if ri <= shells[n + 1]), radial - 1)
        theta = np.degrees(np.arccos(np.clip(z / ri, -1, 1)))
        phi = np.degrees(np.arctan2(y, x)) % 360.0
        e = min(int(theta // (180.0 / elevation)), elevation - 1)
        a = min(int(phi // (360.0 / azimuth)), azimuth - 1)
        vol = ((shells[j + 1] ** 3 - shells[j] ** 3) / 3.0
               * (np.cos(np.radians(e * 180.0 / elevation))
                  - np.cos(np.radians((e + 1) * 180.0 / elevation))) * (2 * np.pi / azimuth))
        density = np.sum(np.linalg.norm(points - points[k], axis=1) <= 0.2 * radius)
        hist[a, e, j] += 1.0 / (density * vol ** (1 / 3))
    h = hist.reshape(-1)
    return h / np.linalg.norm(h)


def _bin_votes(u, n, cyclic):
    """(bin, weight) pairs of linear interpolation between bin centres at integers."""
    lo = int(np.floor(u))
    f = u - lo
    out = []
    for b, w in ((lo, 1 - f), (lo + 1, f)):
        out.append((b % n if cyclic else min(max(b, 0), n - 1), w))
    return out


def shot_loop(points, normals, centre, radius, frame):
    """SHOT of one keypoint: 32 volumes × 11 cosine bins, quadrilinear votes."""
    d, r, idx = _neighbours(points, centre, radius)
    hist = np.zeros((2, 2, 8, 11))                            # radial, elevation, azimuth, bin
    for di, ri, k in zip(d, r, idx):
        q = frame.T @ di
        cos = np.clip(normals[k] @ frame[:, 2], -1, 1)
        az = np.arctan2(q[1], q[0])
        el = np.arctan2(q[2], np.hypot(q[0], q[1]))
        for b, wb in _bin_votes((1 + cos) / 2 * 11 - 0.5, 11, False):
            for a, wa in _bin_votes((az + np.pi) / (2 * np.pi) * 8 - 0.5, 8, True):
                for e, we in _bin_votes((el + np.pi / 2) / np.pi * 2 - 0.5, 2, False):
                    for s, ws in _bin_votes(ri / radius * 2 - 0.5, 2, False):
                        hist[s, e, a, b] += wb * wa * we * ws
    h = hist.reshape(-1)
    return h / np.linalg.norm(h)


def spin_image_loop(points, normal, centre, radius, width=8):
    d, _, _ = _neighbours(points, centre, radius)
    img = np.zeros((2 * width + 1, width + 1))                 # β rows, α columns
    for di in d:
        beta = di @ normal
        alpha = np.sqrt(max(di @ di - beta ** 2, 0.0))
        for row, wr in _bin_votes(beta / radius * width + width, 2 * width + 1, False):
            for col, wc in _bin_votes(alpha / radius * width, width + 1, False):
                img[row, col] += wr * wc
    h = img.reshape(-1)
    return h / np.linalg.norm(h)


def shifted_batch_stats(variables, rng):
    """``variables`` with every batch statistic moved by U(0.2, 0.8), so that a test
    exercises the batch-norm affine step instead of the (0, 1) initial statistics."""
    stats = jax.tree_util.tree_map(
        lambda a: a + jnp.asarray(rng.uniform(0.2, 0.8, a.shape), jnp.float32),
        variables["batch_stats"])
    return {"params": variables["params"], "batch_stats": stats}


def init(model, *inputs, seed=0, **kwargs):
    """``model.init(PRNGKey(seed), *inputs, **kwargs)`` under ``jax.jit``: run eagerly, a
    spherical network's init dispatches its transforms op by op (measured: 25 s against 2.9 s
    for a bandwidth-8 Compass), the same values to 3e-8."""
    return jax.jit(functools.partial(model.init, **kwargs))(jax.random.PRNGKey(seed), *inputs)


def apply(model, variables, *inputs, **kwargs):
    """``model.apply(variables, *inputs, **kwargs)`` under ``jax.jit`` (see :func:`init`)."""
    return jax.jit(functools.partial(model.apply, **kwargs))(variables, *inputs)
