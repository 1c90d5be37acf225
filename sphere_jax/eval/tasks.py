"""Evaluation tasks as plug-ins: ``config.task`` names a module of this package whose
``run(config, workdir, progress) -> (rows, markdown)`` runs the whole evaluation, writes its
tables (:mod:`report`: markdown + CSV) and plots in ``workdir`` and returns them.
``python -m experiments.evaluate`` is a thin main over :func:`run`.

A new task is a module with such a ``run`` and one line in :data:`TASKS`.
"""
from __future__ import annotations

import importlib

from sphere_jax import checks

TASKS = {
    "registration": "sphere_jax.eval.registration",      # seed 4.1-4.4: FMR, inlier ratio, RR
    "lrf": "sphere_jax.eval.repeatability",              # seed 3.2: LRF repeatability
    "classification": "sphere_jax.eval.classification",  # seed 3.3: NR / AR accuracy
    "recognition": "sphere_jax.eval.recognition",        # seed ch. 5: Saliency Boost
    "objects": "sphere_jax.eval.objects",                # seed ch. 6: colour + shape
    "pose": "sphere_jax.eval.pose",                      # seed ch. 7: pose pipeline
    "ablation": "sphere_jax.eval.ablation",              # seed Table 4.5: LEAD variants
}


def task_module(name):
    """The module of task ``name`` (imported on demand: each pulls in its own libraries)."""
    if name not in TASKS:
        raise checks.ConfigError("config.task", f"one of {', '.join(TASKS)}", name)
    return importlib.import_module(TASKS[name])


def run(config, workdir, progress=True):
    """Run the evaluation ``config.task``; returns ``(rows, markdown)``. Config values are
    checked first (:func:`sphere_jax.checks.config_values`)."""
    module = task_module(config.task)
    checks.config_values(config)
    return module.run(config, workdir, progress)
