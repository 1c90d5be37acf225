"""Stages suite: where a shipped spherical network spends its time, stage by stage.

For the shipped Compass and LEAD (``--only`` to pick one), on one chunk of real patches (as
``describe`` streams them) of a 3DMatch fragment (redkitchen 0; a synthetic room's without the real scans), each stage of the
fused network jitted on its own and timed warm (median of ``--repeats``): the patch signal,
the S2 analysis, and per layer the spectral product and the pointwise step (synthesis on the
layer's grid, batch norm, ReLU, analysis to the next bandwidth), then the last synthesis and
what reads the map (Compass's soft-argmax, LEAD's rotation to its frame). Each row: ms per
keypoint, GFLOP per keypoint (XLA's cost analysis, lowered with one block so that every block
counts) and the rate against this run's float32 matmul peak. ``whole`` is the bundle's jitted
network in one call; the stages' outputs are checked against it.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import jax

from experiments.benchmarks import common
from sphere_jax.parallel import DEFAULT_CHUNK

KINDS = ("compass", "lead")
CHUNK = DEFAULT_CHUNK           # patches per call, as `describe` streams them


@dataclasses.dataclass(frozen=True)
class Stage:
    name: str
    fn: object          # jitted, takes ``args``
    args: tuple


def _stack(bundle):
    """``(SphericalStack attributes, its variables)`` of a Compass or LEAD bundle."""
    model = bundle.model
    name = "encoder" if "encoder" in bundle.variables["params"] else "SphericalStack_0"
    variables = {k: v[name] for k, v in bundle.variables.items()}
    return dict(features=tuple(model.features), bandwidths=tuple(model.bandwidths),
                grid=getattr(model, "grid", "near_identity"),
                n_shells=model.n_shells), variables


def _affine(variables, i, spectrum):
    """Inference batch norm ``(scale [C], shift [C])`` of layer ``i``: the model's own
    :class:`layers.GridBatchNorm` applied to the layer's output ``spectrum``."""
    from sphere_jax.spherical import layers
    name = f"GridBatchNorm_{i}"
    return layers.GridBatchNorm().apply({k: v[name] for k, v in variables.items()}, spectrum,
                                        False)


def stages(bundle, patches, frames=None):
    """The fused network of ``bundle`` (Compass or LEAD) as :class:`Stage` s, each run once on
    ``patches`` to feed the next; returns ``(stages, final output)``."""
    from sphere_jax.spherical import correlation, fused, signal, soft_argmax
    from sphere_jax.models.lead import canonical_descriptors
    attrs, variables = _stack(bundle)
    bw, feats = attrs["bandwidths"], attrs["features"]
    out = []

    def step(name, fn, *args):
        fn = jax.jit(fn)
        out.append(Stage(name, fn, args))
        return jax.block_until_ready(fn(*args))

    x = step("signal", lambda p: signal.patch_signals(p, 1.0, bw[0], attrs["n_shells"]), patches)
    coeffs = step("S2 analysis", lambda s: fused.analyse(s, bw[1], False).coeffs, x)
    spec = (coeffs, x.shape[1], bw[0], False)           # coefficients, channels, B, on SO(3)
    last = len(feats) - 1
    for i, c_out in enumerate(feats):
        w = variables["params"][("S2Conv_0" if i == 0 else f"SO3Conv_{i - 1}")]["kernel"]
        grid = correlation.make_grid(attrs["grid"], i > 0, bw[i])
        c_in, b_in, on_so3 = spec[1:]
        kw = dict(c_in=c_in, b_in=b_in, on_so3=on_so3, grid=grid, b_out=bw[i + 1])

        def product(c, w, c_in, b_in, on_so3, grid, b_out):
            return fused.correlate(fused.Spectrum(c, c_in, b_in, on_so3), w, grid, b_out)

        label = f"layer {i}: {'S2' if i == 0 else 'SO(3)'} {b_in}->{bw[i + 1]}, {c_in}->{c_out}"
        if i == 0:       # an S2 product stays factored; the pointwise step forms it per block
            h, h_in = (lambda c, w=w, kw=kw: product(c, w, **kw)), spec[0]
        else:
            h_in = step(f"{label}, product", lambda c, w, kw=kw: product(c, w, **kw).coeffs,
                       spec[0], w)
            h = lambda c, ch=c_out, b=bw[i + 1]: fused.Spectrum(c, ch, b, True)
        scale, shift = _affine(variables, i, h(h_in))
        if i < last:
            coeffs = step(f"{label}, pointwise to L={bw[i + 2]}",
                         lambda c, sc, sh, h=h, i=i: fused.pointwise(h(c), sc, sh,
                                                                     bw[i + 2]).coeffs,
                         h_in, scale, shift)
            spec = (coeffs, c_out, bw[i + 1], True)
        else:
            maps = step("last synthesis", lambda c, sc, sh, h=h: (
                fused.synthesise(h(c)) * sc[:, None, None, None] + sh[:, None, None, None]
            )[:, 0], h_in, scale, shift)
    if bundle.kind == "compass":
        model = bundle.model
        final = step("soft-argmax", jax.vmap(lambda m: soft_argmax.soft_argmax_rotation(
            m, model.temperature, model.window)), maps)
    else:
        final = step("rotation to the frame", canonical_descriptors, maps, frames)
    return out, final


def run(repeats=5, only=None, **_):
    from experiments.benchmarks.describe import fragments, unrolled_gflop
    from experiments.benchmarks.layers import matmul_gflops
    from sphere_jax import api, paths
    peak = matmul_gflops()
    frag, _ = fragments(4 * CHUNK)
    records = []
    for kind in KINDS:
        if only and only not in kind:
            continue
        bundle = api.cached_bundle(paths.shipped_bundle(kind, required=True))
        stream = bundle.supports(frag.points, frag.keypoints[:2 * CHUNK])
        stream.check("mask")                     # keypoints with too little support: left out
        x = np.asarray(stream.make(0, min(CHUNK, stream.n))[0], np.float32)
        frames = np.broadcast_to(np.eye(3, dtype=np.float32), (len(x), 3, 3))
        parts, final = stages(bundle, x, frames)
        whole = Stage("whole", bundle._orient_fn, (x,)) if kind == "compass" else \
            Stage("whole", bundle._describe_fn, (x, frames))
        expected = jax.block_until_ready(whole.fn(*whole.args))
        err = float(np.max(np.abs(np.asarray(final) - np.asarray(expected))))
        if err > 1e-4:
            raise AssertionError(f"{kind}: the stages give another output than the network "
                                 f"(max difference {err:.2e})")
        for stage in parts + [whole]:
            ms = common.median_ms(lambda: stage.fn(*stage.args), repeats) / len(x)
            gflop = unrolled_gflop(stage.fn, *stage.args) / len(x)
            rate = gflop / (ms * 1e-3)
            records.append({"network": f"{kind}_mid", "stage": stage.name,
                            "ms_per_keypoint": round(ms, 3),
                            "gflop_per_keypoint": round(gflop, 4),
                            "gflop_per_s": round(rate, 1),
                            "peak_fraction": round(rate / peak, 3),
                            "matmul_gflop_per_s": round(peak, 1)})
    return records
