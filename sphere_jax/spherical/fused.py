"""A spherical CNN with its layers chained in the spectral domain, for inference and training.

Between two correlations the network leaves the spectral domain only for its pointwise step
(batch norm — a per-channel affine map once its statistics are known, which :func:`moments`
takes from the spectrum — and ReLU)::

    spectrum h (bandwidth B) -> SO(3) synthesis -> a·x + b, ReLU -> analysis to L' -> next product

That step acts on every (patch, channel) signal on its own, so it runs in blocks of signals
whose grids stay in the CPU cache, and the backward pass recomputes them block by block
(:func:`_blocked_map`) and runs each block's adjoint as the same pipeline with transposed
tables (:func:`_block_step`). A layer-by-layer pass instead writes every grid to memory and reads it
back several times (for 40 channels at B = 16 that is 5 MB per patch). At inference that
traffic bounds the transforms on a CPU (LEAD 'paper' describes 2.6× faster fused); a training
step at 'paper' size is bound by the transforms' arithmetic on both paths (docs/performance.md).

Inside a block the layouts differ from :mod:`transforms`: spectra are ``[h, 2(re/im),
2L-1(m), L/2(n'), L(l), x]`` with n = 2n' + h, and grids ``[2, 2, B, B, 2B(β), x]``, so that
each step — Wigner-d in β, DFT in α, DFT in γ — is one GEMM (or a GEMM batched over its leading
axes) with no transposes in between. Both uniform axes are split radix 2, which halves their
DFTs: α by the parity of its grid index (:func:`_half_dft`), γ by the parity of the frequency n
(the two halves of the γ grid differ by (-1)^n). The grid's order is therefore permuted, which
is invisible outside since it never leaves the block. The results equal
:mod:`correlation`'s to float32 round-off (tests/test_fused.py).
"""
from __future__ import annotations

import functools
import typing

import numpy as np
import jax
import jax.numpy as jnp

from sphere_jax.spherical import correlation, so3, transforms

# Grid floats per block: 5 MB of float32 grid (one patch × 40 channels at B = 16) measured
# fastest on the 2-core development machine (L2 1 MB/core, L3 32 MB); larger blocks spill.
BLOCK_FLOATS = 40 * 32 ** 3


class Spectrum(typing.NamedTuple):
    """Internal SO(3) or S2 spectrum of N patches × C channels (layouts of :mod:`transforms`:
    S2 ``[L, L, 2, N·C]``, SO(3) ``[2L-1, L, L, 2, N·C]``) and the bandwidth of the grid it was
    analysed from."""
    coeffs: jax.Array
    channels: int
    bandwidth: int
    on_so3: bool

    @property
    def lmax(self) -> int:
        return self.coeffs.shape[1]

    @property
    def n_patches(self) -> int:
        return self.coeffs.shape[-1] // self.channels

    # A block of signals is computed from windows of ``operands`` on their last axis
    # (``windows(start, size)``: one ``(offset, length)`` each, lengths static) by ``from_pieces``;
    # :func:`pointwise` differentiates through that split without forming whole-batch grids.
    def operands(self):
        return (self.coeffs,)

    def windows(self, start, size: int):
        return ((start, size),)

    def from_pieces(self, pieces, size: int):
        return pieces[0]

    def block(self, start, size: int):
        """Coefficients of signals ``start .. start + size`` (``start`` may be traced)."""
        return self.from_pieces(_windows(self.operands(), self.windows(start, size)), size)


class S2Product(typing.NamedTuple):
    """The SO(3) spectrum of an S2 correlation, left as its factors: with few input channels
    the product is cheap to redo per block, and its dense output (40 channels at B = 16:
    2·31·16·16 floats per channel) is as large as a grid — not worth writing to memory."""
    f: Spectrum
    kernel: jax.Array              # s2_kernel_spectrum blocks
    channels: int
    bandwidth: int
    on_so3 = True

    @property
    def lmax(self) -> int:
        return self.bandwidth

    @property
    def n_patches(self) -> int:
        return self.f.n_patches

    def operands(self):
        return (self.f.coeffs, self.kernel)

    def windows(self, start, size: int):
        """Whole patches (``size`` a multiple of the channels: their input signals and the
        whole kernel) or some channels of one patch (``size`` divides the channels: the
        patch's input signals and those output channels of the kernel)."""
        c, c_in = self.channels, self.f.channels
        if size % c == 0:
            return (start // c * c_in, size // c * c_in), (0, c)
        return (start // c * c_in, c_in), (start % c, size)

    def from_pieces(self, pieces, size: int):
        f, kernel = pieces
        count = max(1, size // self.channels)
        h = correlation.s2_spectral_product(f.reshape(f.shape[:-1] + (count, self.f.channels)),
                                            kernel)
        return h.reshape(h.shape[:-2] + (-1,))

    def block(self, start, size: int):
        """Signals ``start .. start + size`` (see :meth:`windows`)."""
        return self.from_pieces(_windows(self.operands(), self.windows(start, size)), size)

    @property
    def coeffs(self):
        return self.block(0, self.n_patches * self.channels)


def analyse(x, lmax: int, on_so3: bool) -> Spectrum:
    """Grids ``[N, C, 2B, 2B(, 2B)]`` -> :class:`Spectrum` truncated to ``lmax``."""
    grid_ndim = 3 if on_so3 else 2
    b = transforms.grid_bandwidth(x, grid_ndim)
    n, c = x.shape[:2]
    flat = jnp.asarray(x, jnp.float32).reshape((n * c,) + x.shape[2:])
    fn = transforms.so3_analysis if on_so3 else transforms.s2_analysis
    return Spectrum(fn(flat, lmax), c, b, on_so3)


def truncate(f: Spectrum, lmax: int) -> Spectrum:
    """The spectrum's degrees below ``lmax``: what analysing its grid to ``lmax`` would give
    (per-degree quadrature), so one analysis can feed layers of different output bandwidths."""
    if not 1 <= lmax <= f.lmax:
        raise ValueError(f"lmax must be in [1, {f.lmax}] (the spectrum's), got {lmax}")
    if lmax == f.lmax:
        return f
    big = f.lmax
    c = f.coeffs[:lmax, :lmax] if not f.on_so3 else \
        f.coeffs[big - lmax:big + lmax - 1, :lmax, :lmax]
    return f._replace(coeffs=c)


def correlate(f: Spectrum, w, grid, b_out: int):
    """The spectral product of :mod:`correlation` on a spectrum already truncated to ``b_out``:
    the output's SO(3) spectrum (bandwidth ``b_out``), as a :class:`Spectrum` or, from S2, an
    :class:`S2Product` that :func:`pointwise` evaluates block by block."""
    if f.lmax != b_out:
        raise ValueError(f"spectrum has lmax={f.lmax}, the layer needs b_out={b_out}")
    if not f.on_so3:
        return S2Product(f, correlation.s2_kernel_spectrum(w, grid, b_out), w.shape[-1], b_out)
    h = correlation.spectral_product(f.coeffs, f.channels, w, grid, b_out, on_so3=True)
    return Spectrum(h, w.shape[-1], b_out, True)


def moments(h):
    """Haar mean and mean square ``([N, C], [N, C])`` of the SO(3) signals of ``h``
    (:class:`Spectrum` on SO(3) or :class:`S2Product`), from the spectrum alone
    (:func:`transforms.so3_moments`): the batch statistics of :class:`layers.GridBatchNorm`."""
    if not h.on_so3:
        raise ValueError("moments are of SO(3) signals; got an S2 spectrum")
    if isinstance(h, S2Product):          # from its factors: the product is never formed
        f = h.f.coeffs
        mean, mean_sq = correlation.s2_product_moments(
            f.reshape(f.shape[:-1] + (h.n_patches, h.f.channels)), h.kernel)
    else:
        mean, mean_sq = transforms.so3_moments(h.coeffs)
    shape = (h.n_patches, h.channels)
    return mean.reshape(shape), mean_sq.reshape(shape)


def synthesise(h: Spectrum):
    """SO(3) spectrum -> grids ``[N, C, 2B, 2B, 2B]`` at its bandwidth."""
    y = transforms.so3_synthesis(h.coeffs, h.bandwidth)
    return y.reshape((-1, h.channels) + y.shape[1:])


# ----------------------------------------------------------------------------------------------
# Blocked pointwise step
# ----------------------------------------------------------------------------------------------

def _half_dft(b: int, inverse: bool):
    """The α DFT split by the parity p of the grid index a = 2a' + p (radix 2): frequencies m
    and m - B differ on sub-grid p by the factor (-1)^p, so each sub-grid needs only the B
    folded frequencies q = m mod B — half the multiplications of the full DFT.

    ``inverse``: ``e^{iqα}``, ``[p, a', r(re/im out), s(re/im in), q]``; else ``e^{-iqα}``,
    ``[p, s(out), q, a', r(in)]``; float64."""
    alpha = so3.grid_alpha(b).reshape(b, 2).T                          # [p, a']: a = 2a' + p
    angle = alpha[:, :, None] * np.arange(b)                           # [p, a', q]
    c, s = np.cos(angle), np.sin(angle)
    if inverse:    # (x_re + i x_im)(cos + i sin)
        return np.stack([np.stack([c, -s], 2), np.stack([s, c], 2)], 2)
    # (x_re + i x_im)(cos - i sin), output axes first
    t = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], 1)    # [p, s, a', q, r]
    return t.transpose(0, 1, 3, 2, 4)


def _by_parity(t, axis: int, length: int):
    """Zero-pad ``t``'s axis ``axis`` to ``length`` (even) and split it as n = 2n' + h into
    ``(n', h)``, with h moved to the front."""
    pad = [(0, 0)] * t.ndim
    pad[axis] = (0, length - t.shape[axis])
    t = np.pad(t, pad).reshape(t.shape[:axis] + (length // 2, 2) + t.shape[axis + 1:])
    return np.moveaxis(t, axis + 1, 0)


def _even(n: int) -> int:
    return n + n % 2


@functools.lru_cache(maxsize=None)
def _block_tables(b: int, l_in: int, l_out: int):
    """Synthesis tables at (B, L_in) and analysis tables at (B, L_out) in the block layouts, n
    split by parity (padded to even counts); the leading axes the GEMMs batch over are tiled
    (XLA wants batch axes on both operands)."""
    d_syn = _by_parity(transforms.so3_tables(b, l_in)[1], 1, _even(l_in))    # [h, m, n', l, j]
    d_ana = _by_parity(transforms.so3_tables(b, l_out)[0], 1, _even(l_out))  # [h, m, n', l, j]
    # γ_{g+B} = γ_g + π, so frequency n takes the factor (-1)^n on the γ grid's second half:
    # each parity h of n needs only the B points g < B.
    g_syn = _by_parity(transforms.inverse_dft(b, l_in, False)[..., :b], 0, _even(l_in))
    g_ana = _by_parity(transforms.forward_dft(b, l_out, False)[:b], 2, _even(l_out))
    tile = lambda t, reps: np.broadcast_to(t, reps + t.shape[len(reps):])
    return tuple(transforms.table_f32(t) for t in (
        tile(d_syn.transpose(0, 1, 2, 4, 3)[:, None], (2, 2)),         # [h, s, m, n', j, l]
        tile(_half_dft(b, inverse=True)[:, None], (2, 2)),             # [p, h, a', r, s, q]
        tile(g_syn.transpose(0, 3, 2, 1)[None, :, None], (2, 2, b)),   # [p, h, a', g', r, n']
        tile(g_ana.transpose(0, 2, 3, 1)[None, :, None], (2, 2, b)),   # [p, h, a', r, n', g']
        tile(_half_dft(b, inverse=False)[:, None], (2, 2)),            # [p, h, s, q, a', r]
        tile(d_ana[:, None], (2, 2))))                                 # [h, s, m, n', l, j]


@functools.lru_cache(maxsize=None)
def _adjoint_tables(b: int, l_in: int, l_out: int):
    """The tables of :func:`_block_tables` transposed for the backward pass, in the same
    roles: the adjoint of the step runs the analysis tables as a synthesis and the other way
    round, and each table in the layout of the one whose role it takes keeps every backward
    GEMM a plain one (autodiff's transposed GEMMs moved grid-sized operands first)."""
    d_syn, a_syn, g_syn, g_ana, a_ana, d_ana = _block_tables(b, l_in, l_out)
    t = lambda x, axes: np.ascontiguousarray(np.transpose(x, axes))
    return (t(d_ana, (0, 1, 2, 3, 5, 4)), t(a_ana, (0, 1, 4, 5, 2, 3)),
            t(g_ana, (0, 1, 2, 5, 3, 4)), t(g_syn, (0, 1, 2, 4, 5, 3)),
            t(a_syn, (0, 1, 4, 5, 2, 3)), t(d_syn, (0, 1, 2, 3, 5, 4)))


def _sum_diff(a, b, axis: int):
    """``[a + b, a - b]`` stacked on ``axis``: the radix-2 butterfly of both splits."""
    return jnp.stack([a + b, a - b], axis)


def _fold(y, b, axis):
    """Frequencies ``2L-1 (m)`` on ``axis`` -> ``[p, ..., B (q), ...]``: ``c_q ± c_{q-B}``
    (p = 0, 1), the inputs of the half-size α DFTs; frequencies beyond ``±(L-1)`` are zero."""
    l = (y.shape[axis] + 1) // 2
    pad = [(0, 0)] * y.ndim
    pad[axis] = (b - l, b - l)
    y = jnp.pad(y, pad)                                                # m = -(B-1) .. B-1
    hi = jax.lax.slice_in_dim(y, b - 1, 2 * b - 1, axis=axis)          # m = q
    pad[axis] = (1, 0)
    lo = jnp.pad(jax.lax.slice_in_dim(y, 0, b - 1, axis=axis), pad)    # m = q - B (0 at q = 0)
    return _sum_diff(hi, lo, 0)


def _unfold(y, l, axis):
    """Inverse of the fold for analysis, ``[p, ..., B (q), ...]`` -> ``c_m = Y_0[q] ± Y_1[q]``
    (+ for m ≥ 0, - for m < 0, q = m mod B) as ``[..., 2L-1 (m), ...]`` (``axis`` counts
    without p)."""
    b = y.shape[axis + 1]
    y0, y1 = y[0], y[1]
    neg = lambda t: jax.lax.slice_in_dim(t, b - l + 1, b, axis=axis)
    pos = lambda t: jax.lax.slice_in_dim(t, 0, l, axis=axis)
    return jnp.concatenate([neg(y0) - neg(y1), pos(y0) + pos(y1)], axis)


def _bmm(lhs, rhs, batch: int, contract: int):
    """Batched GEMM ``[*batch, *m, *k] @ [*batch, *k, *n] -> [*batch, *m, *n]`` over the
    leading ``batch`` axes and the ``contract`` axes between. jnp.einsum may list several
    contracting axes in an order that is not the memory order, and XLA then transposes the
    grid-sized operand first; naming them in order keeps every step a plain GEMM."""
    b_dims = tuple(range(batch))
    k_lhs = tuple(range(lhs.ndim - contract, lhs.ndim))
    k_rhs = tuple(range(batch, batch + contract))
    return jax.lax.dot_general(lhs, rhs, ((k_lhs, k_rhs), (b_dims, b_dims)))


def _synthesis(h_HxSxMxNxLxX, tables):
    """β, α, γ synthesis of a block: spectra ``[h, s, m, n', l, x]`` -> ``[p, h, a', g', j,
    x]`` (α index 2a' + p, β index j; γ index g' + tB once the butterfly over h is applied)."""
    d_syn, a_syn, g_syn = tables[:3]
    y = _bmm(d_syn, h_HxSxMxNxLxX, 4, 1)                              # β
    y = _bmm(a_syn, _fold(y, a_syn.shape[2], 2), 2, 2)                 # α
    return _bmm(g_syn, y, 3, 2)                                        # γ of each parity


def _analysis(z_PxHxAxGxJxX, tables):
    """γ, α, β analysis of a block, the inverse layouts of :func:`_synthesis`."""
    g_ana, a_ana, d_ana = tables[3:]
    y = _bmm(g_ana, z_PxHxAxGxJxX, 3, 1)                              # γ
    y = _bmm(a_ana, y, 2, 2)                                           # α
    y = _unfold(y, (d_ana.shape[2] + 1) // 2, 2)                       # [h, s, m, n', j, x]
    return _bmm(d_ana, y, 4, 1)                                        # β


def _block_step(tables, adjoint, relu: bool):
    """The pointwise step of one block, ``(h [h, s, m, n', l, x], scale [x], shift [x]) ->
    spectra [h, s, m, n', l', x]``, n split by parity h (n = 2n' + h), with its backward pass
    written out.

    Between the transforms the grid's two γ halves are the butterfly ``z_0 ± z_1`` of the
    parities. The backward pass is the same pipeline on the cotangent with the ``adjoint``
    tables (:func:`_adjoint_tables`; both butterflies, the α fold and unfold are each other's
    transposes) around the activation's derivative, and needs only the forward's synthesis:
    9 GEMMs per block where autodiff ran 12, none with a transposed operand."""
    def act(u, scale, shift):
        u = u * scale + shift
        return jax.nn.relu(u) if relu else u

    def forward(h, scale, shift):
        z = _synthesis(h, tables)
        # Both butterflies and the activation in one expression, so that XLA makes them one
        # pass over the grid: stacking the γ halves in between split it in two (Compass's
        # B = 12 step on 256 patches, one core: 16.0 + 15.8 -> 15.8 ms, the step 210 -> 192 ms).
        grid_0, grid_1 = act(z[:, 0] + z[:, 1], scale, shift), act(z[:, 0] - z[:, 1], scale,
                                                                    shift)
        return _analysis(_sum_diff(grid_0, grid_1, 1), tables), z

    @jax.custom_vjp
    def step(h, scale, shift):
        return forward(h, scale, shift)[0]

    def step_fwd(h, scale, shift):
        out, z = forward(h, scale, shift)
        return out, (z, scale, shift)

    def step_bwd(res, ct):
        z, scale, shift = res
        c = _synthesis(ct, adjoint)
        grads = []
        for u, c_t in ((z[:, 0] + z[:, 1], c[:, 0] + c[:, 1]),
                       (z[:, 0] - z[:, 1], c[:, 0] - c[:, 1])):
            e = c_t * (u * scale + shift > 0) if relu else c_t
            grads.append((e, u))
        axes = tuple(range(z.ndim - 2))
        ct_h = _analysis(_sum_diff(grads[0][0] * scale, grads[1][0] * scale, 1), adjoint)
        return (ct_h, sum(jnp.sum(e * u, axes) for e, u in grads),
                sum(jnp.sum(e, axes) for e, _ in grads))

    step.defvjp(step_fwd, step_bwd)
    return step


def _signals_per_block(n_patches, channels, b, block_floats):
    """Signals per block: whole patches (a divisor of ``n_patches`` times the channels) or, when
    one patch's grids exceed ``block_floats``, a divisor of the channels; the largest that fits
    (at least 1)."""
    target = max(1, block_floats // (2 * b) ** 3)
    sizes = [k * channels for k in range(1, n_patches + 1) if n_patches % k == 0]
    sizes += [d for d in range(1, channels) if channels % d == 0]
    return max([x for x in sizes if x <= target] or [1])


def _windows(arrays, windows):
    """``array[..., offset:offset + length]`` for each array and its window (offset traced)."""
    return tuple(jax.lax.dynamic_slice_in_dim(a, o, n, a.ndim - 1)
                 for a, (o, n) in zip(arrays, windows))


def _blocked_map(fn, arrays, windows, n_blocks: int, out_shape):
    """``out[..., i·S:(i+1)·S] = fn(*windows of arrays for block i)`` for i < ``n_blocks``
    (S = ``out_shape[-1] / n_blocks``), differentiable in ``arrays``.

    Plain autodiff of the loop would store every block's grids for the backward pass — the
    whole batch's grids, which is what the blocks are there to avoid — and add a full-size
    cotangent per block. The backward pass here instead recomputes each block's forward
    (rematerialisation, as ``jax.checkpoint`` does) and adds its cotangents into their windows
    in place, so memory stays a block's grids plus the spectra."""
    size = out_shape[-1] // n_blocks

    def forward(arrs):
        def body(i, out):
            block = fn(*_windows(arrs, windows(i * size, size)))
            return jax.lax.dynamic_update_slice_in_dim(out, block, i * size, out.ndim - 1)
        return jax.lax.fori_loop(0, n_blocks, body, jnp.zeros(out_shape, jnp.float32))

    @jax.custom_vjp
    def run(arrs):
        return forward(arrs)

    def run_fwd(arrs):
        return forward(arrs), arrs

    def run_bwd(arrs, ct):
        def body(i, cts):
            spans = windows(i * size, size)
            _, vjp = jax.vjp(fn, *_windows(arrs, spans))
            got = vjp(jax.lax.dynamic_slice_in_dim(ct, i * size, size, ct.ndim - 1))
            out = []
            for c, g, (o, n) in zip(cts, got, spans):
                cur = jax.lax.dynamic_slice_in_dim(c, o, n, c.ndim - 1)
                out.append(jax.lax.dynamic_update_slice_in_dim(c, cur + g, o, c.ndim - 1))
            return tuple(out)
        return (jax.lax.fori_loop(0, n_blocks, body, tuple(jnp.zeros_like(a) for a in arrs)),)

    run.defvjp(run_fwd, run_bwd)
    return run(tuple(arrays))


def pointwise(h, scale_C, shift_C, lmax_out: int, relu: bool = True,
              block_floats: int | None = None) -> Spectrum:
    """``analysis_{lmax_out}(ReLU(scale · synthesis(h) + shift))`` per channel, in cache-sized
    blocks of signals; differentiable in ``h``'s arrays, ``scale`` and ``shift``, with the
    block grids recomputed in the backward pass (:func:`_blocked_map`). ``h``:
    :class:`Spectrum` or :class:`S2Product`; ``scale_C``, ``shift_C``: ``[C]``;
    ``block_floats``: grid floats per block (default :data:`BLOCK_FLOATS`)."""
    b, l_in, c = h.bandwidth, h.lmax, h.channels
    transforms.check_sizes(b, lmax_out, "bandwidth")
    tables, adjoint = (tuple(jnp.asarray(t, jnp.float32) for t in fn(b, l_in, lmax_out))
                       for fn in (_block_tables, _adjoint_tables))
    step = _block_step(tables, adjoint, relu)
    n = h.n_patches
    size = _signals_per_block(n, c, b, block_floats or BLOCK_FLOATS)
    # A block of whole patches takes the same per-signal scale and shift as every other block:
    # one array for all, read whole. A slice at the block's offset (or a tile inside the loop)
    # is fused into the grid's activation and makes that pass 3-4x slower (2.1 against 0.57 ms
    # for 80 signals at B = 12 on one core).
    whole = size % c == 0
    scale, shift = (jnp.tile(jnp.asarray(t, jnp.float32), size // c if whole else n)
                    for t in (scale_C, shift_C))
    operands = h.operands()
    k = len(operands)

    # Blocks are sliced off the minor (signal) axis in place: transposing the whole spectrum to
    # put blocks first would cost two extra passes over memory.
    def block(*pieces):
        hb = h.from_pieces(pieces[:k], size)                           # [m, n, l, s, x]
        hb = jnp.pad(hb, ((0, 0), (0, _even(l_in) - l_in)) + ((0, 0),) * 3)
        hb = hb.reshape(hb.shape[:1] + (-1, 2) + hb.shape[2:])
        fb = step(jnp.transpose(hb, (2, 4, 0, 1, 3, 5)),              # [h, s, m, n', l, x]
                  pieces[k], pieces[k + 1])
        fb = jnp.transpose(fb, (2, 3, 0, 4, 1, 5))                     # [m, n', h, l, s, x]
        return fb.reshape(fb.shape[:1] + (-1,) + fb.shape[3:])[:, :lmax_out]

    def windows(start, size):
        channels = (0, size) if whole else (start, size)
        return h.windows(start, size) + (channels, channels)

    out_shape = (2 * lmax_out - 1, lmax_out, lmax_out, 2, n * c)
    coeffs = _blocked_map(block, operands + (scale, shift), windows, n * c // size, out_shape)
    return Spectrum(coeffs, c, b, True)
