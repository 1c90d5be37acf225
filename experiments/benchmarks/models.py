"""Models suite: forward time of every config at its configured batch (training steps: the
``train`` suite), and
LEAD/SOUND description time per keypoint for 5000 keypoints of the 3DMatch kitchen fragment
(when the real scans are present), with the fused inference path of
:mod:`sphere_jax.spherical.fused` (the default) and layer by layer (``unfused``), with
``describe_workers`` chunks of the config's ``infer_chunk`` keypoints run at a time
(:func:`sphere_jax.parallel.run_chunked`). ``--only=lead`` keeps the configs whose name contains
it."""
from __future__ import annotations

import importlib
import json
import os
import sys
import time

import jax
import numpy as np

from experiments.benchmarks import common
from sphere_jax import models, parallel, paths
from sphere_jax.bundles import inference
from sphere_jax.data import patches
from sphere_jax.data.readers import io


def run(sizes=("small", "paper"), repeats=3, keypoints=5000, only=None, **_):
    """Forward time per config and size; description ms per keypoint."""
    records = []
    shared = paths.real_data("3dmatch", "7-scenes-redkitchen", "cloud_bin_0.ply")
    down = kp = None
    if shared and os.path.isfile(shared):
        down = patches.voxel_downsample(io.read_ply(shared).points, 0.02)
        kp = patches.random_keypoints(down, keypoints, np.random.default_rng(0))
    for name in ("compass", "lead", "lead_pn", "sound"):
        if only and only not in name:
            continue
        for size in sizes:
            config = importlib.import_module(f"configs.{name}").get_config(size)
            model = models.build(config)
            bs, n = config.train.batch_size, config.data.n_points
            rng = np.random.default_rng(0)
            p = (rng.normal(size=(bs, n, 3)) * 0.4).astype(np.float32)
            variables = jax.jit(lambda x: model.init(jax.random.PRNGKey(0), x, train=False))(p)
            fwd = jax.jit(lambda v, x: model.apply(v, x, train=False))
            fwd_ms = common.median_ms(lambda: fwd(variables, p), repeats)
            rec = {"config": f"{name}:{size}", "batch": bs, "fwd_ms": round(fwd_ms, 1),
                   "describe_ms_per_kp": "",
                   "unfused_ms_per_kp": "", "describe_workers": ""}
            # The models with a fused path that describe (LEAD, SOUND): fused vs layer by layer.
            if (hasattr(model, "fused") and models.spec(config.model).describe is not None
                    and down is not None):
                for key, fused in (("describe_ms_per_kp", True), ("unfused_ms_per_kp", False)):
                    bundle = inference.Bundle(model.clone(fused=fused), variables, config)
                    # Keypoints with too little support are left out, as the evaluations do.
                    describe = lambda k: bundle.describe(down, k, radius=0.3,
                                                         on_invalid="mask")[1]
                    describe(kp[:256])                                   # compile
                    t0 = time.perf_counter()
                    described = int(np.sum(describe(kp)))
                    rec[key] = round(1e3 * (time.perf_counter() - t0) / described, 3)
                rec["describe_workers"] = parallel.default_workers()     # chunks run at a time
            records.append(rec)
            print(json.dumps(rec), file=sys.stderr, flush=True)     # partial results survive
    return records
