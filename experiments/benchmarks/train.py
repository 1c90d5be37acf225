"""Train suite: the training step of compass, lead and sound at each size, fused (spectral
domain, the default) and layer by layer, on 1 and 2 devices — the real loop of
:func:`sphere_jax.training.train_and_evaluate` (background batches from the embedded scans,
sharded over a data-parallel mesh), timed over ``repeats`` steps after one warm-up step.

Every measurement runs in a fresh process, so its peak RSS is its own (compilation included)
and its device count can be set: on a CPU the devices are host devices
(``--xla_force_host_platform_device_count``) sharing the machine's cores. Records: ``config``,
``path``, ``devices``, ``batch``, ``step_ms``, ``patches_per_s``, ``peak_rss_gb``,
``data_wait_frac`` (share of the loop's time spent waiting for a batch).
"""
from __future__ import annotations

import importlib
import json
import os
import re
import resource
import subprocess
import sys
import time

MODELS = ("compass", "lead", "sound")


def measure(name: str, size: str, fused: bool, devices: int, steps: int) -> dict:
    """One record, in this process (which must see ``devices`` local devices)."""
    import jax

    from sphere_jax import parallel, training
    from sphere_jax.data.prefetch import Prefetch

    config = importlib.import_module(f"configs.{name}").get_config(size)
    config.train.update(fused=fused, devices=devices)
    source = training.build_source(config)
    mesh = parallel.make_mesh(devices)
    parallel.check_batch_size(config.train.batch_size, mesh)
    model = training.training_model(config)
    tx = training.optimiser()
    state = parallel.replicate(
        training.init_state(config, model, tx, training.get_batch(config, source, 0)), mesh)
    step_fn, _ = training.make_steps(config, model, tx, mesh)
    make = lambda s: parallel.shard_batch(training.get_batch(config, source, s), mesh)
    with Prefetch(make, range(steps + 1)) as batches:
        t0 = wait0 = None
        for s, batch in batches:
            state, metrics = step_fn(state, batch)
            jax.block_until_ready(metrics)
            if s == 0:                                   # compilation
                t0, wait0 = time.perf_counter(), batches.wait_s
        wall = time.perf_counter() - t0
        wait = batches.wait_s - wait0
    bs = config.train.batch_size
    return {"config": f"{name}:{size}", "path": "fused" if fused else "layers",
            "devices": devices, "batch": bs, "step_ms": round(1e3 * wall / steps, 1),
            "patches_per_s": round(bs * steps / wall, 2),
            "peak_rss_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 20, 2),
            "data_wait_frac": round(wait / wall, 4)}


def _child_env(devices: int) -> dict:
    env = dict(os.environ)
    flags = re.sub(r"--xla_force_host_platform_device_count=\d+", "", env.get("XLA_FLAGS", ""))
    env["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={devices}".strip()
    return env


def run(sizes=("small", "paper"), repeats=3, only=None, devices=(1, 2), **_):
    records = []
    for name in MODELS:
        if only and only not in name:
            continue
        for size in sizes:
            for fused in (True, False):
                for n in devices:
                    cmd = [sys.executable, "-m", "experiments.benchmarks.train", name, size,
                           str(int(fused)), str(n), str(repeats)]
                    out = subprocess.run(cmd, env=_child_env(n), capture_output=True, text=True)
                    if out.returncode != 0:
                        raise RuntimeError(f"{' '.join(cmd[2:])} failed:\n{out.stderr[-3000:]}")
                    rec = json.loads(out.stdout.strip().splitlines()[-1])
                    records.append(rec)
                    print(json.dumps(rec), file=sys.stderr, flush=True)  # partial results
    return records


if __name__ == "__main__":                     # one measurement: NAME SIZE FUSED DEVICES STEPS
    name, size, fused, n, steps = sys.argv[1:6]
    print(json.dumps(measure(name, size, fused == "1", int(n), int(steps))))
