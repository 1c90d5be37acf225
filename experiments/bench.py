"""Benchmarks that print tables: ``python -m experiments.bench --suite=layers [--json]``.

Patches suite (``--suite=patches``): 5000 patches of 1225 points (radius 0.3 m) from a 3DMatch
fragment voxelised at 2 cm — the real one in ``../shared/data`` when present, else a synthetic
fragment — timing keypoint selection and patch extraction, then the spherical signals.

Models suite (``--suite=models [--sizes=cpu,paper]``): forward and training-step time of every
config at its configured batch, and LEAD/SOUND description time per keypoint for 5000 keypoints
of the 3DMatch kitchen fragment (when ``../shared/data`` is present), with the fused inference
path of :mod:`sphere_jax.spherical.fused` (the default) and layer by layer (``unfused``), with
``describe_workers`` chunks of the config's ``infer_chunk`` keypoints run at a time
(:func:`sphere_jax.api.run_chunked`). ``--only=lead`` keeps the configs whose name contains it.

Registration suite (``--suite=registration``): one 3DMatch pair (kitchen 0–5 from
``../shared/data``, else the first synthetic pair) with 5000 keypoints per fragment, evaluated
end to end with FPFH, SHOT and LEAD (the shipped bundle): seconds per stage and in total,
JIT compilation included — the issue's target is 60 s on 2 cores.

Layers suite: every spherical layer of the seed's models at batch 8 — forward and
forward+backward time (median of ``--repeats`` runs after warm-up), jit compile time, FLOPs of
the per-degree spectral products and the GFLOP/s they reach alone, next to this machine's
float32 matmul GFLOP/s measured in the same run.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time

import numpy as np
import jax
import jax.numpy as jnp

from sphere_jax.spherical import correlation, layers, transforms

# (kind, c_in, c_out, b_in, b_out): Compass, LEAD and SOUND layers (CONVENTIONS.md §7).
LAYERS = [
    ("S2Conv", 4, 40, 24, 24), ("S2Conv", 4, 40, 24, 16),
    ("SO3Conv", 40, 20, 24, 24), ("SO3Conv", 20, 10, 24, 24),
    ("SO3Conv", 40, 40, 16, 12), ("SO3Conv", 40, 40, 16, 16), ("SO3Conv", 40, 40, 12, 8),
    ("SO3Conv", 40, 40, 8, 6), ("SO3Conv", 40, 1, 6, 4),
]


def shared_data(*parts):
    """A path in the real scans beside the project (``../shared/data``); may not exist."""
    return os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", *parts)


def _median_ms(fn, repeats):
    jax.block_until_ready(fn())                                      # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def matmul_gflops(n=2048, repeats=10):
    """float32 GEMM throughput of this machine (the roofline the products are measured by)."""
    a = jax.random.normal(jax.random.PRNGKey(0), (n, n))
    f = jax.jit(lambda x, y: x @ y)
    ms = _median_ms(lambda: f(a, a), repeats)
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
    fwd_ms = _median_ms(lambda: fwd_compiled(params, x), repeats)

    loss = lambda p, v: jnp.sum(model.apply(p, v) ** 2)
    fwd_bwd = jax.jit(jax.value_and_grad(loss, argnums=(0, 1))).lower(params, x).compile()
    fwd_bwd_ms = _median_ms(lambda: fwd_bwd(params, x), repeats)

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
    product_ms = _median_ms(lambda: product(f_hat, spec), repeats)
    gflop = correlation.product_flops("so3" if on_so3 else "s2", batch, b_out, c_in, c_out) / 1e9
    return {"layer": f"{kind} {c_in}->{c_out} B{b_in}->{b_out}", "batch": batch,
            "fwd_ms": round(fwd_ms, 2), "fwd_bwd_ms": round(fwd_bwd_ms, 2),
            "compile_s": round(compile_s, 2), "product_ms": round(product_ms, 2),
            "gflop": round(gflop, 4), "gflop_per_s": round(gflop / (product_ms * 1e-3), 1)}


def run_layers(batch=8, repeats=5, only=None):
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


def run_patches(repeats=5):
    from sphere_jax.spherical import signal
    from sphere_jax.data import io, patches, synthetic
    shared = shared_data("3dmatch", "demo_fullres", "cloud_bin_0.ply")
    if os.path.isfile(shared):
        source, points = "3DMatch demo cloud_bin_0 (../shared/data)", io.read_ply(shared).points
    else:
        scene_dir = os.path.join(synthetic.ensure_default_data(), "3dmatch", "synth-room-0")
        source = "synthetic synth-room-0 cloud_bin_0"
        points = io.read_ply(os.path.join(scene_dir, "cloud_bin_0.ply")).points
    t0 = time.perf_counter()
    down = patches.voxel_downsample(points, 0.02)
    voxel_ms = 1e3 * (time.perf_counter() - t0)
    times, out = [], None
    for seed in range(repeats):
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        kp = patches.random_keypoints(down, 5000, rng)
        out = patches.extract_patches(down, kp, 0.3, 1225, rng, min_points=300)
        times.append(time.perf_counter() - t0)
    batch = jnp.asarray(out.points[:512])
    signal.patch_signals(batch, 0.3, 24).block_until_ready()
    sig_ms = _median_ms(lambda: signal.patch_signals(batch, 0.3, 24), repeats)
    return [{"source": source, "points": len(points), "voxel_2cm_points": len(down),
             "voxel_ms": round(voxel_ms, 1), "patches": len(out.keypoints),
             "extract_ms": round(1e3 * statistics.median(times), 1),
             "signals_512_B24_ms": round(sig_ms, 1)}]


def run_models(sizes=("cpu", "paper"), repeats=3, keypoints=5000, only=None):
    """Forward and training-step time per config and size; description ms per keypoint."""
    import importlib
    import optax
    from sphere_jax import api, training
    from sphere_jax.data import io, patches
    records = []
    shared = shared_data("3dmatch", "7-scenes-redkitchen", "cloud_bin_0.ply")
    down = kp = None
    if os.path.isfile(shared):
        down = patches.voxel_downsample(io.read_ply(shared).points, 0.02)
        kp = patches.random_keypoints(down, keypoints, np.random.default_rng(0))
    for name in ("compass", "lead", "lead_pn", "sound"):
        if only and only not in name:
            continue
        for size in sizes:
            config = importlib.import_module(f"configs.{name}").get_config(size)
            model = models.build(config)
            tx = optax.adam(config.train.learning_rate)
            bs, n = config.train.batch_size, config.data.n_points
            rng = np.random.default_rng(0)
            p = (rng.normal(size=(bs, n, 3)) * 0.4).astype(np.float32)
            batch = {"patches": p}
            if name in ("compass", "sound"):
                rots = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(bs)])
                batch.update(copies=p, rotations=rots.astype(np.float32))
            state = training.init_state(config, model, tx, batch)
            step, _ = training.make_steps(config, model, tx)
            variables = {"params": state["params"], "batch_stats": state["batch_stats"]}
            fwd = jax.jit(lambda v, x: model.apply(v, x, train=False))
            fwd_ms = _median_ms(lambda: fwd(variables, p), repeats)
            step_ms = _median_ms(lambda: step(state, batch)[1]["loss"], repeats)
            rec = {"config": f"{name}:{size}", "batch": bs, "fwd_ms": round(fwd_ms, 1),
                   "train_step_ms": round(step_ms, 1), "describe_ms_per_kp": "",
                   "unfused_ms_per_kp": "", "describe_workers": ""}
            if name in ("lead", "sound") and down is not None:
                for key, fused in (("describe_ms_per_kp", True), ("unfused_ms_per_kp", False)):
                    bundle = api.Bundle(model.clone(fused=fused), variables, config)
                    bundle.describe(down, kp[:256], radius=0.3)          # compile
                    t0 = time.perf_counter()
                    bundle.describe(down, kp, radius=0.3)
                    rec[key] = round(1e3 * (time.perf_counter() - t0) / len(kp), 3)
                rec["describe_workers"] = api.default_workers()     # chunks run at a time
            records.append(rec)
            print(json.dumps(rec), file=sys.stderr, flush=True)     # partial results survive
    return records


def run_registration(keypoints=5000, methods=("fpfh", "shot", "lead")):
    """Seconds per stage of one pair's evaluation, end to end (compilation included)."""
    from configs import eval_common
    from sphere_jax.data import datasets, pipeline
    from sphere_jax.eval import methods as method_lib, registration, scenes
    kitchen = shared_data("3dmatch", "7-scenes-redkitchen")
    if os.path.isdir(kitchen):
        pair_set = scenes.fragment_scene(datasets.load_fragment_scene(kitchen,
                                                                      kitchen + "-evaluation"))
        pair = (0, 5)
    else:
        pair_set = scenes.find_pair_sets(pipeline.default_scan_root())[0]
        pair = pair_set.pairs[0]
    bundles = {k: eval_common.shipped(f"{k}_cpu") for k in ("lead", "compass", "sound")}
    records, total = [], time.perf_counter()

    def stage(name, fn):
        t0 = time.perf_counter()
        out = fn()
        records.append({"pair": f"{pair_set.name} {pair}", "stage": name,
                        "seconds": round(time.perf_counter() - t0, 2)})
        print(json.dumps(records[-1]), file=sys.stderr, flush=True)
        return out

    frags = stage("prepare (voxel, normals, keypoints)", lambda: {
        k: scenes.prepare(pair_set, k, n_keypoints=keypoints) for k in pair})
    for m in methods:
        describe = method_lib.descriptor(m, 0.30, bundles, 0.15)
        desc = stage(f"{m}: describe 2x{keypoints}", lambda: {k: describe(f)
                                                            for k, f in frags.items()})
        row = stage(f"{m}: match + RANSAC", lambda: registration.match_pair(
            frags[pair[0]], frags[pair[1]], desc[pair[0]], desc[pair[1]],
            pair_set.transforms[pair]))
        records[-1]["seconds"] = f"{records[-1]['seconds']} (RRE {row['rre_deg']:.1f} deg)"
    records.append({"pair": f"{pair_set.name} {pair}", "stage": "total",
                    "seconds": round(time.perf_counter() - total, 2)})
    return records


def machine_line():
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPU cores, "
            f"jax {jax.__version__} ({jax.default_backend()})")


def format_table(records):
    cols = list(records[0])
    rows = [[str(r[c]) for c in cols] for r in records]
    widths = [max(len(c), *(len(row[i]) for row in rows)) for i, c in enumerate(cols)]
    line = lambda cells: "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths)) + " |"
    return "\n".join([line(cols), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
                     + [line(r) for r in rows])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", choices=["layers", "patches", "models", "registration"], default="layers")
    parser.add_argument("--sizes", default="cpu,paper", help="models suite: config sizes")
    parser.add_argument("--keypoints", type=int, default=5000,
                        help="models/registration suites: keypoints per fragment")
    parser.add_argument("--json", action="store_true", help="print one JSON list of records")
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", default=None,
                        help="layers/models suites: keep the layers or configs whose name "
                        "contains this")
    args = parser.parse_args(argv)
    if args.suite == "patches":
        records = run_patches(args.repeats)
    elif args.suite == "registration":
        records = run_registration(args.keypoints)
    elif args.suite == "models":
        records = run_models(tuple(args.sizes.split(",")), min(args.repeats, 3), args.keypoints,
                             args.only)
    else:
        records = run_layers(args.batch, args.repeats, args.only)
    if args.json:
        print(json.dumps(records))
    else:
        print(f"machine: {machine_line()}")
        print(format_table(records))


if __name__ == "__main__":
    main()
