"""Stages suite: where a shipped spherical network spends its time, stage by stage.

For the shipped Compass, LEAD and SOUND (``--only`` to pick one), on one chunk of real
patches (as ``describe`` streams them) of a 3DMatch fragment (redkitchen 0; a synthetic room's
without the real scans), each stage of the fused network jitted on its own and timed warm
(median of ``--repeats``): the patch signal, the S2 analysis, and per layer the spectral
product and the pointwise step (synthesis on the layer's grid, batch norm, ReLU, analysis to
the next bandwidth), then the last synthesis and what reads the map (Compass's soft-argmax,
LEAD's rotation to its frame; SOUND: its shared layer, then each branch, its soft-argmax and
the rotation of its map to that frame). Each row: ms per
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
from sphere_jax.models import shipped

KINDS = ("compass", "lead", "sound")
CHUNK = DEFAULT_CHUNK           # patches per call, as `describe` streams them


@dataclasses.dataclass(frozen=True)
class Stage:
    name: str
    fn: object          # jitted, takes ``args``
    args: tuple


def _stack(model, variables, name):
    """``(attributes, variables)`` of the :class:`SphericalStack` ``name`` of a bundle."""
    return dict(features=tuple(model.features), bandwidths=tuple(model.bandwidths),
                grid=getattr(model, "grid", "near_identity")), \
        {k: v[name] for k, v in variables.items()}


def _affine(variables, name, spectrum):
    """Inference batch norm ``(scale [C], shift [C])``: the model's own
    :class:`layers.GridBatchNorm` ``name`` applied to the layer's output ``spectrum``."""
    from sphere_jax.spherical import layers
    return layers.GridBatchNorm().apply({k: v[name] for k, v in variables.items()}, spectrum,
                                        False)


def _layers(step, attrs, variables, spec, s2_first=True, tag=""):
    """The stages of one stack's layers on ``spec`` = ``(coefficients, channels, B, on SO(3))``
    (a spectrum at the stack's ``bandwidths[1]``); returns its last synthesis, the maps."""
    from sphere_jax.spherical import correlation, fused
    bw, feats = attrs["bandwidths"], attrs["features"]
    last = len(feats) - 1

    def product(c, w, c_in, b_in, on_so3, grid, b_out):
        return fused.correlate(fused.Spectrum(c, c_in, b_in, on_so3), w, grid, b_out)

    for i, c_out in enumerate(feats):
        s2 = i == 0 and s2_first
        conv = "S2Conv_0" if s2 else f"SO3Conv_{i - 1 if s2_first else i}"
        w = variables["params"][conv]["kernel"]
        c_in, b_in, on_so3 = spec[1:]
        kw = dict(c_in=c_in, b_in=b_in, on_so3=on_so3, b_out=bw[i + 1],
                  grid=correlation.make_grid(attrs["grid"], not s2, bw[i]))
        label = f"{tag}layer {i}: {'S2' if s2 else 'SO(3)'} {b_in}->{bw[i + 1]}, {c_in}->{c_out}"
        if s2:           # an S2 product stays factored; the pointwise step forms it per block
            h, h_in = (lambda c, w=w, kw=kw: product(c, w, **kw)), spec[0]
        else:
            h_in = step(f"{label}, product", lambda c, w, kw=kw: product(c, w, **kw).coeffs,
                        spec[0], w)
            h = lambda c, ch=c_out, b=bw[i + 1]: fused.Spectrum(c, ch, b, True)
        scale, shift = _affine(variables, f"GridBatchNorm_{i}", h(h_in))
        if i < last:
            coeffs = step(f"{label}, pointwise to L={bw[i + 2]}",
                          lambda c, sc, sh, h=h, i=i: fused.pointwise(h(c), sc, sh,
                                                                      bw[i + 2]).coeffs,
                          h_in, scale, shift)
            spec = (coeffs, c_out, bw[i + 1], True)
        else:
            return step(f"{tag}last synthesis", lambda c, sc, sh, h=h: (
                fused.synthesise(h(c)) * sc[:, None, None, None] + sh[:, None, None, None]
            )[:, 0], h_in, scale, shift)


def stages(bundle, patches, frames=None):
    """The fused network of ``bundle`` (Compass, LEAD or SOUND) as :class:`Stage` s, each run
    once on ``patches`` to feed the next; returns ``(stages, final output)``. SOUND: its
    shared S2 layer, then the descriptor branch and the LRF branch, each from the shared
    spectrum truncated to its bandwidth (untimed: a slice)."""
    from sphere_jax.spherical import correlation, fused, signal, soft_argmax
    from sphere_jax.models.lead import canonical_descriptors
    model, variables, out = bundle.model, bundle.variables, []

    def step(name, fn, *args):
        fn = jax.jit(fn)
        out.append(Stage(name, fn, args))
        return jax.block_until_ready(fn(*args))

    argmax = jax.vmap(lambda m: soft_argmax.soft_argmax_rotation(m, model.temperature,
                                                                 model.window))
    if bundle.kind == "sound":
        b0, b1 = model.s2_bandwidths
        x = step("signal", lambda p: signal.patch_signals(p, 1.0, b0, model.n_shells), patches)
        coeffs = step("S2 analysis", lambda s: fused.analyse(s, b1, False).coeffs, x)
        w = variables["params"]["s2"]["kernel"]
        lmax = max(model.descriptor_bandwidths[1], model.lrf_bandwidths[1])
        c_out = model.s2_features
        h = lambda c: fused.correlate(fused.Spectrum(c, x.shape[1], b0, False), w,
                                      correlation.make_grid("near_identity", False, b0), b1)
        scale, shift = _affine(variables, "s2_norm", h(coeffs))
        shared = step(f"shared layer: S2 {b0}->{b1}, {x.shape[1]}->{c_out}, pointwise to "
                      f"L={lmax}", lambda c, sc, sh: fused.pointwise(h(c), sc, sh, lmax).coeffs,
                      coeffs, scale, shift)
        maps = {}
        for branch, bws, feats in (("descriptor", model.descriptor_bandwidths,
                                    model.descriptor_features),
                                   ("lrf", model.lrf_bandwidths, model.lrf_features)):
            attrs = dict(features=tuple(feats), bandwidths=tuple(bws), grid="near_identity")
            start = fused.truncate(fused.Spectrum(shared, c_out, b1, True), bws[1])
            maps[branch] = _layers(step, attrs, {k: v[branch] for k, v in variables.items()},
                                   (start.coeffs, c_out, b1, True), s2_first=False,
                                   tag=f"{branch} ")
        rot = step("lrf soft-argmax", argmax, maps["lrf"])
        return out, step("rotation to its own frame", canonical_descriptors, maps["descriptor"],
                         rot)
    name = "encoder" if "encoder" in variables["params"] else "SphericalStack_0"
    attrs, stack_vars = _stack(model, variables, name)
    bw = attrs["bandwidths"]
    x = step("signal", lambda p: signal.patch_signals(p, 1.0, bw[0], model.n_shells), patches)
    coeffs = step("S2 analysis", lambda s: fused.analyse(s, bw[1], False).coeffs, x)
    maps = _layers(step, attrs, stack_vars, (coeffs, x.shape[1], bw[0], False))
    if bundle.kind == "compass":
        return out, step("soft-argmax", argmax, maps)
    return out, step("rotation to the frame", canonical_descriptors, maps, frames)


def whole_network(bundle, patches, frames):
    """The bundle's jitted network in one call, as a :class:`Stage`: what its spec has — an
    orienting network (Compass) has no describe function, and only a descriptor whose spec
    says ``describe_frames`` (LEAD) takes ``frames``."""
    if bundle.spec.describe is None:
        return Stage("whole", bundle._orient_fn, (patches,))
    args = (patches, frames) if bundle.spec.describe_frames else (patches,)
    return Stage("whole", bundle._describe_fn, args)


def run(repeats=5, only=None, **_):
    from experiments.benchmarks.describe import fragments, unrolled_gflop
    from experiments.benchmarks.layers import matmul_gflops
    from sphere_jax.bundles import inference
    peak = matmul_gflops()
    frag, _ = fragments(4 * CHUNK)
    records = []
    for kind in KINDS:
        if only and only not in kind:
            continue
        bundle = inference.cached_bundle(shipped.bundle_path(kind, required=True))
        stream = bundle.supports(frag.points, frag.keypoints[:2 * CHUNK])
        stream.check("mask")                     # keypoints with too little support: left out
        x = np.asarray(stream.make(0, min(CHUNK, stream.n))[0], np.float32)
        frames = np.broadcast_to(np.eye(3, dtype=np.float32), (len(x), 3, 3))
        parts, final = stages(bundle, x, frames)
        whole = whole_network(bundle, x, frames)
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
