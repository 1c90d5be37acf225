"""Layers suite: every spherical layer of the seed's models at batch 8 — forward and
forward+backward time (median of ``--repeats`` runs after warm-up), jit compile time, FLOPs of
the per-degree spectral products and the GFLOP/s they reach alone, next to this machine's
float32 matmul GFLOP/s measured in the same run."""
from __future__ import annotations

import time

import jax
import jax.numpy as jnp

from experiments.benchmarks import common
from sphere_jax.spherical import correlation, layers, transforms

# (kind, c_in, c_out, b_in, b_out): Compass, LEAD and SOUND layers (CONVENTIONS.md §7).
LAYERS = [
    ("S2Conv", 4, 40, 24, 24), ("S2Conv", 4, 40, 24, 16),
    ("SO3Conv", 40, 20, 24, 24), ("SO3Conv", 20, 10, 24, 24),
    ("SO3Conv", 40, 40, 16, 12), ("SO3Conv", 40, 40, 16, 16), ("SO3Conv", 40, 40, 12, 8),
    ("SO3Conv", 40, 40, 8, 6), ("SO3Conv", 40, 1, 6, 4),
]


def matmul_gflops(n=2048, repeats=10):
    """float32 GEMM throughput of this machine (the roofline the products are measured by)."""
    a = jax.random.normal(jax.random.PRNGKey(0), (n, n))
    f = jax.jit(lambda x, y: x @ y)
    ms = common.median_ms(lambda: f(a, a), repeats)
    return 2 * n ** 3 / (ms * 1e-3) / 1e9


def bench_layer(kind, c_in, c_out, b_in, b_out, batch=8, repeats=5):
    on_so3 = kind == "SO3Conv"
    grid_shape = (batch, c_in) + (2 * b_in,) * (3 if on_so3 else 2)
    x = jax.random.normal(jax.random.PRNGKey(0), grid_shape)
    model = (layers.SO3Conv if on_so3 else layers.S2Conv)(c_out, b_in, b_out)
    params = model.init(jax.random.PRNGKey(1), x)

    fwd = jax.jit(model.apply)
    t0 = time.perf_counter()
    fwd_compiled = fwd.lower(params, x).compile()
    compile_s = time.perf_counter() - t0
    fwd_ms = common.median_ms(lambda: fwd_compiled(params, x), repeats)

    loss = lambda p, v: jnp.sum(model.apply(p, v) ** 2)
    fwd_bwd = jax.jit(jax.value_and_grad(loss, argnums=(0, 1))).lower(params, x).compile()
    fwd_bwd_ms = common.median_ms(lambda: fwd_bwd(params, x), repeats)

    # The per-degree products alone, on precomputed spectra.
    w = params["params"]["kernel"]
    grid = correlation.make_grid("near_identity", on_so3)
    x_flat = x.reshape((batch * c_in,) + x.shape[2:])
    if on_so3:
        f_hat = transforms.so3_analysis(x_flat, b_out)
        spec = correlation.so3_kernel_spectrum(w, grid, b_out)
        product = jax.jit(correlation.so3_spectral_product)
    else:
        f_hat = transforms.s2_analysis(x_flat, b_out)
        spec = correlation.s2_kernel_spectrum(w, grid, b_out)
        product = jax.jit(correlation.s2_spectral_product)
    f_hat = f_hat.reshape(f_hat.shape[:-1] + (batch, c_in))
    product_ms = common.median_ms(lambda: product(f_hat, spec), repeats)
    gflop = correlation.product_flops("so3" if on_so3 else "s2", batch, b_out, c_in, c_out) / 1e9
    return {"layer": f"{kind} {c_in}->{c_out} B{b_in}->{b_out}", "batch": batch,
            "fwd_ms": round(fwd_ms, 2), "fwd_bwd_ms": round(fwd_bwd_ms, 2),
            "compile_s": round(compile_s, 2), "product_ms": round(product_ms, 2),
            "gflop": round(gflop, 4), "gflop_per_s": round(gflop / (product_ms * 1e-3), 1)}


def run(batch=8, repeats=5, only=None, **_):
    records = []
    for spec in LAYERS:
        name = f"{spec[0]} {spec[1]}->{spec[2]} B{spec[3]}->{spec[4]}"
        if only and only not in name:
            continue
        records.append(bench_layer(*spec, batch=batch, repeats=repeats))
    mm = round(matmul_gflops(), 1)
    for r in records:
        r["matmul_gflop_per_s"] = mm
    return records
