"""Train a model: ``python -m experiments.train --config=sound[:cpu|:tiny] [--workdir=DIR]``.

``--config`` takes an experiment name (``sound``), ``name:size`` or a config file path
(``configs/sound.py:cpu``); fields are overridden with ``--config.train.steps=200`` and the
like. Running the same command again resumes from the newest checkpoint in the workdir.
"""
from __future__ import annotations

import os
import sys

from absl import app, flags, logging
from ml_collections import config_flags

from configs import resolve_config_arg
from sphere_jax import training

config_flags.DEFINE_config_file("config", None, "experiment config (name, name:size or path)")
flags.DEFINE_string("workdir", None, "where checkpoints, metrics and the bundle go "
                                     "(default: runs/<model>_<size>)")


def main(_):
    logging.set_verbosity(logging.WARNING)          # orbax logs every save at INFO
    config = flags.FLAGS.config
    if config is None:
        raise app.UsageError("--config is required, e.g. --config=sound:cpu")
    workdir = flags.FLAGS.workdir or os.path.join("runs", f"{config.model}_{config.size}")
    _, last = training.train_and_evaluate(config, workdir)
    print(f"finished in {workdir}: " + ", ".join(f"{k}={v:.4g}" for k, v in last.items()
                                                  if isinstance(v, float)))


if __name__ == "__main__":
    sys.argv = resolve_config_arg(sys.argv)
    app.run(main)
