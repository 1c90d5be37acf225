"""Peers suite: our S2 and SO(3) transforms against s2fft's, in one run and in float32, at
B = 8, 16, 24, 32 on batches of 40 signals (s2fft transforms one signal per call: vmapped and
jitted here). s2fft's two JAX methods are timed — precompute (kernels built beforehand, not
timed) and on-the-fly recursions — and the faster is reported, with the largest difference
between its output and ours after the convention conversion
(:func:`sphere_jax.spherical.s2fft_compat.to_s2fft`), relative to the largest magnitude.
Needs the ``bench`` extra (``pip install -e '.[bench]'``).
"""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from experiments.benchmarks import common
from sphere_jax.spherical import transforms
from sphere_jax.spherical.s2fft_compat import to_s2fft

BANDWIDTHS, BATCH = (8, 16, 24, 32), 40


def _s2fft_methods(transform, b):
    """``{method: jitted fn on one s2fft-layout signal or coefficient array}``."""
    from s2fft.precompute_transforms import construct, spherical, wigner
    from s2fft.transforms import spherical as otf_s2, wigner as otf_so3
    kw = dict(sampling="dh", reality=True)
    forward = transform.endswith("forward")
    if transform.startswith("s2"):
        kernel = construct.spin_spherical_kernel_jax(b, reality=True, sampling="dh",
                                                     forward=forward)
        pre = functools.partial(spherical.forward if forward else spherical.inverse, L=b,
                                kernel=kernel, method="jax", **kw)
        otf = functools.partial(otf_s2.forward_jax if forward else otf_s2.inverse_jax, L=b,
                                **kw)
    else:
        kernel = construct.wigner_kernel_jax(b, b, reality=True, sampling="dh",
                                             forward=forward)
        pre = functools.partial(wigner.forward if forward else wigner.inverse, L=b, N=b,
                                kernel=kernel, method="jax", **kw)
        otf = functools.partial(otf_so3.forward_jax if forward else otf_so3.inverse_jax, L=b,
                                N=b, **kw)
    return {"precompute": jax.jit(jax.vmap(pre)), "on-the-fly": jax.jit(jax.vmap(otf))}


def _case(transform, b, rng):
    """``(ours jitted, our input, s2fft input, kind of the output)``."""
    on_so3 = transform.startswith("so3")
    grid = rng.normal(size=(BATCH,) + (2 * b,) * (3 if on_so3 else 2)).astype(np.float32)
    fft, ifft = ((transforms.so3_fft, transforms.so3_ifft) if on_so3 else
                 (transforms.s2_fft, transforms.s2_ifft))
    grid = np.asarray(ifft(fft(jnp.asarray(grid)), b))           # band-limited to L = B
    space = "so3" if on_so3 else "s2"
    if transform.endswith("forward"):
        return (jax.jit(fft), grid, to_s2fft(grid, f"{space}_grid").astype(np.float32),
                f"{space}_coeffs")
    coeffs = np.asarray(fft(jnp.asarray(grid)))
    return (jax.jit(functools.partial(ifft, b=b)), coeffs,
            to_s2fft(coeffs, f"{space}_coeffs").astype(np.complex64), f"{space}_grid")


def run(repeats=5, **_):
    records = []
    rng = np.random.default_rng(0)
    for b in BANDWIDTHS:
        for transform in ("s2_forward", "s2_inverse", "so3_forward", "so3_inverse"):
            ours, x, theirs_in, out_kind = _case(transform, b, rng)
            ours_in = jnp.asarray(x)
            ours_ms = common.median_ms(lambda: ours(ours_in), repeats)
            expected = to_s2fft(np.asarray(ours(ours_in)), out_kind)
            best = None
            for method, fn in _s2fft_methods(transform, b).items():
                arg = jnp.asarray(theirs_in)
                ms = common.median_ms(lambda: fn(arg), repeats)
                if best is None or ms < best[1]:
                    got = np.asarray(fn(arg))
                    got = np.real(got) if np.isrealobj(expected) else got
                    diff = np.abs(got - expected).max() / np.abs(got).max()
                    best = (method, ms, float(diff))
            records.append({"transform": transform, "b": b, "batch": BATCH,
                            "ours_ms": round(ours_ms, 2), "s2fft_ms": round(best[1], 2),
                            "s2fft_method": best[0], "max_rel_diff": float(f"{best[2]:.2e}")})
    return records
