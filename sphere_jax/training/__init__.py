"""Training: ``python -m experiments.train`` runs :func:`train_and_evaluate`.

===============  ============================================================================
``loop``         loss, schedule, optimiser, state, the jitted data-parallel steps, the loop
``inputs``       the config's data source and the batch of a step
``checkpoints``  orbax checkpoints, resume, the workdir's claim, the bundle at the end
``adaptation``   a bundle adapted to unlabelled scans with its own loss
``side_by_side`` several bundles adapted at once, each on its share of the cores
===============  ============================================================================

Continuing a bundle at its step, or fine-tuning from its weights, is :mod:`sphere_jax.bundle`'s.
"""
from sphere_jax.training.adaptation import adapt
from sphere_jax.training.checkpoints import WORKDIR_CONFIG
from sphere_jax.training.inputs import build_source, get_batch
from sphere_jax.training.loop import (TrainingError, init_state, learning_rate_schedule, loss_fn,
                                      make_steps, optimiser, train_and_evaluate, training_model)

__all__ = ["TrainingError", "WORKDIR_CONFIG", "adapt", "build_source", "get_batch",
           "init_state", "learning_rate_schedule", "loss_fn", "make_steps", "optimiser",
           "train_and_evaluate", "training_model"]
