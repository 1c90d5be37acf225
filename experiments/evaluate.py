"""Evaluations: ``python -m experiments.evaluate --config=eval_registration[:quick]``.

``--config`` takes an evaluation config — ``eval_registration``, ``eval_lrf``,
``eval_classification``, ``eval_recognition``, ``eval_objects``, ``eval_pose`` (optionally
``:quick``, ``:tiny``, ``eval_lrf:stanford``, ``eval_classification:small``) — or a config file
path; its ``task`` chooses the plug-in of :mod:`sphere_jax.eval.tasks`. Fields are overridden
with ``--config.x=...``
(``--config.methods=fpfh,shot,sound``, ``--config.bundle=runs/sound_small/bundle``,
``--config.data.root=DIR``, ``--config.rotate=True``). Tables are printed and written with the
CSV and plots to the workdir (default ``runs/<config name>``).

Several processes (``jax.distributed``): start the same command in each with
``--coordinator=HOST:PORT --num_processes=N --process_id=I`` (or ``--distributed`` under
Slurm / Open MPI); the registration and LRF evaluations split their scenes over the
processes and process 0 writes the merged tables.
"""
from __future__ import annotations

import os
import time

from absl import app, flags, logging
from ml_collections import config_flags

from experiments import cli
from sphere_jax.eval import tasks

config_flags.DEFINE_config_file("config", None, "evaluation config (name[:arg] or path)")
flags.DEFINE_string("workdir", None, "where the tables and plots go")
flags.DEFINE_bool("distributed", False, "join a multi-process run found by JAX (Slurm, Open "
                  "MPI, TPU): the scenes are split over the processes")
flags.DEFINE_string("coordinator", None, "multi-process run: HOST:PORT of process 0")
flags.DEFINE_integer("num_processes", None, "multi-process run: number of processes")
flags.DEFINE_integer("process_id", None, "multi-process run: this process's index")
flags.DEFINE_float("peer_timeout_s", 60.0, "multi-process run: stop when another process has "
                   "been silent this long (rerun the same command to resume)")


def main(_):
    logging.set_verbosity(logging.WARNING)
    config = flags.FLAGS.config
    if config is None:
        raise app.UsageError("--config is required, e.g. --config=eval_registration:quick")
    suffix = ("_rotated" if config.get("rotate") else "") + (
        "" if config.size == "full" else f"_{config.size}")
    workdir = flags.FLAGS.workdir or os.path.join("runs", f"eval_{config.task}{suffix}")
    f = flags.FLAGS
    if f.distributed or f.coordinator or f.num_processes is not None:
        from sphere_jax import parallel
        parallel.initialize(f.coordinator, f.num_processes, f.process_id, f.peer_timeout_s)
    start = time.perf_counter()
    command = cli.command("experiments.evaluate")
    _, md = tasks.run(config, workdir, command=command)
    if md:                                     # in a multi-process run: process 0 only
        print(md)
        print(f"written to {workdir} in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    cli.run(main)
