"""Benchmarks that print tables: ``python -m experiments.bench --suite=NAME [--json]``.

Suites (one module each in ``experiments/benchmarks/``, whose docstring says what it times):
``layers`` (every spherical layer of the seed's models), ``patches`` (keypoints, patches and
spherical signals on a 3DMatch fragment), ``models`` (forward and description
per config; ``--sizes=small,paper``, ``--only=lead``), ``registration`` (one 3DMatch pair end to
end), ``train`` (training steps fused vs layer by layer on 1 and 2 devices, patches/s, peak RSS,
data wait; ``--sizes``, ``--only``, ``--repeats`` steps), ``peers`` (our S2/SO(3) transforms
against s2fft's at B = 8-32, with their agreement; needs ``pip install -e '.[bench]'``),
``describe`` (per method: ms, GFLOP and share of the matmul peak per keypoint, peak RSS and
``sphere_jax.register`` end to end on a real pair; ``--keypoints``, ``--only``), ``stages``
(the shipped Compass and LEAD stage by stage: ms, GFLOP and share of the peak; ``--only``),
``keypoints`` (register on the 27 redkitchen pairs with a quarter, half and all the keypoints,
and what describing them share by share returns; ``--only=METHOD``, default lead_pn).
``--json`` prints one JSON list of the records instead of the table; ``--record=DIR`` also
writes them with the command, machine and date to ``DIR/bench.json``, which ``python -m
experiments.publish --bench=DIR`` publishes in docs/performance.md.
"""
from __future__ import annotations

import datetime
import importlib
import json
import os

from absl import app, flags

from experiments import cli
from experiments.benchmarks import SUITES, common
from sphere_jax import checks, files

flags.DEFINE_enum("suite", "layers", SUITES, "which benchmark suite to run")
flags.DEFINE_string("sizes", "small,paper", "models/train suites: config sizes, comma-separated")
flags.DEFINE_integer("keypoints", 5000, "models/registration suites: keypoints per fragment")
flags.DEFINE_bool("json", False, "print one JSON list of records instead of the table")
flags.DEFINE_string("record", None, "also write DIR/bench.json (command, machine, date, "
                    "records): what `experiments.publish --bench=DIR` publishes")
flags.DEFINE_integer("batch", 8, "layers suite: batch size")
flags.DEFINE_integer("repeats", 5, "timed runs per measurement (median)")
flags.DEFINE_string("only", None, "layers/models suites: keep the layers or configs whose name "
                    "contains this")


def main(argv):
    if len(argv) > 1:
        raise app.UsageError(f"unexpected arguments {argv[1:]}")
    f = flags.FLAGS
    for flag in ("keypoints", "batch", "repeats"):            # before any suite's set-up
        checks.positive(getattr(f, flag), f"--{flag}", integer=True)
    suite = importlib.import_module(f"experiments.benchmarks.{f.suite}")
    repeats = min(f.repeats, 3) if f.suite in ("models", "train") else f.repeats
    records = suite.run(batch=f.batch, repeats=repeats, only=f.only, keypoints=f.keypoints,
                        sizes=tuple(f.sizes.split(",")))
    if f.record:
        os.makedirs(f.record, exist_ok=True)
        files.atomic_write(os.path.join(f.record, "bench.json"), json.dumps({
            "suite": f.suite, "command": cli.command("experiments.bench"),
            "machine": common.machine_line(), "date": datetime.date.today().isoformat(),
            "records": records}, indent=1) + "\n")
    if f.json:
        print(json.dumps(records))
    else:
        print(f"machine: {common.machine_line()}")
        print(common.format_table(records))


if __name__ == "__main__":
    # What a suite times must not depend on what an earlier command left compiled on disk:
    # no persistent cache here or in the suites' processes, unless one is named (the describe
    # suite measures the warm case in a folder of its own).
    os.environ.setdefault("SPHERE_JAX_COMPILE_CACHE", "off")
    cli.run(main)
