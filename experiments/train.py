"""Train a model: ``python -m experiments.train --config=sound[:small|:tiny] [--workdir=DIR]``.

A descriptor bundle (LEAD, LEAD-PN, SOUND) gets its whitening when the run finishes: fitted on
its own training scans as ``experiments.whiten`` fits it (LEAD's Compass source in the shipped
Compass's frames), so the one command makes the whole bundle (``--nowhiten``: leave it out).

``--config`` takes an experiment name (``sound``), ``name:size`` or a config file path
(``configs/sound.py:small``); fields are overridden with ``--config.train.steps=200`` and the
like. Running the same command again resumes from the newest checkpoint in the workdir, with
any number of devices.

Devices: the batch is split over ``--config.train.devices`` devices per host (default: all).
A CPU host is given ``--host_devices`` devices (default 2), which the data-parallel step runs
side by side: XLA runs the loops of the spectral-domain path on one thread per device.
Several hosts: start the same command on each with ``--coordinator=HOST:PORT
--num_processes=N --process_id=I`` (or ``--distributed`` under Slurm, Open MPI or on a TPU
pod, where JAX finds them itself). A process that dies stops the others within
``--peer_timeout_s`` (exit status 75, naming it); the same command resumes.
"""
from __future__ import annotations

import os
import re

from absl import app, flags, logging
from ml_collections import config_flags

from experiments import cli

config_flags.DEFINE_config_file("config", None, "experiment config (name, name:size or path)")
flags.DEFINE_string("workdir", None, "where checkpoints, metrics and the bundle go "
                                     "(default: runs/<model>_<size>)")
flags.DEFINE_integer("host_devices", 2, "devices a CPU host is split into (ignored when "
                     "XLA_FLAGS already sets --xla_force_host_platform_device_count)")
flags.DEFINE_bool("distributed", False, "join a multi-host run found by JAX (Slurm, Open MPI, "
                  "TPU)")
flags.DEFINE_string("coordinator", None, "multi-host run: HOST:PORT of process 0")
flags.DEFINE_integer("num_processes", None, "multi-host run: number of processes")
flags.DEFINE_integer("process_id", None, "multi-host run: this process's index")
flags.DEFINE_bool("whiten", True, "descriptor bundles: fit the whitening on the training "
                  "scans when the run finishes (experiments.whiten)")
flags.DEFINE_float("peer_timeout_s", 60.0, "multi-host run: stop when another process has been "
                   "silent this long (rerun the same command to resume)")


def _set_host_devices(n: int):
    """Before JAX starts its CPU client: only then does the device count take effect."""
    if n < 1:
        raise app.UsageError(f"--host_devices must be >= 1, got {n}")
    current = os.environ.get("XLA_FLAGS", "")
    if not re.search(r"--xla_force_host_platform_device_count=", current):
        os.environ["XLA_FLAGS"] = f"{current} --xla_force_host_platform_device_count={n}".strip()


def main(_):
    f = flags.FLAGS
    logging.set_verbosity(logging.WARNING)          # orbax logs every save at INFO
    config = f.config
    if config is None:
        raise app.UsageError("--config is required, e.g. --config=sound:small")
    _set_host_devices(f.host_devices)
    import jax              # configured by cli.run, but no backend started: XLA_FLAGS holds
    from sphere_jax import parallel, training
    from sphere_jax.bundles import inference
    from sphere_jax.features import whitening_fit
    if f.distributed or f.coordinator or f.num_processes is not None:
        parallel.initialize(f.coordinator, f.num_processes, f.process_id, f.peer_timeout_s)
    workdir = f.workdir or os.path.join("runs", f"{config.model}_{config.size}")
    command = cli.command("experiments.train")
    orient = inference.shape_orienter(config.orient_bundle) if config.get("orient_bundle") else None
    _, last = training.train_and_evaluate(config, workdir, command=command, orient_shapes=orient)
    if f.whiten and jax.process_index() == 0:
        whitening_fit.fit_if_descriptor(os.path.join(workdir, "bundle"), command=command)
    print(f"finished in {workdir}: " + ", ".join(f"{k}={v:.4g}" for k, v in last.items()
                                                  if isinstance(v, float)))


if __name__ == "__main__":
    cli.run(main)
