"""Shape classification (thesis 3.3): PointNet on whole shapes, trained on labels; on shapes
oriented by a whole-shape Compass it becomes rotation invariant (the ``orient_bundle`` of a
``classify`` config, :func:`sphere_jax.bundles.inference.orient_shapes`)."""
from __future__ import annotations

from typing import NamedTuple, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
import optax

from sphere_jax.models.pointnet import PointNetEncoder
from sphere_jax.models.spec import ModelSpec


class ClassifyOut(NamedTuple):
    logits: jax.Array           # [N, n_classes]


class PointNetClassifier(nn.Module):
    """``points [N, P, 3] -> ClassifyOut``."""
    n_classes: int
    features: Sequence[int] = (64, 64, 64, 128, 1024)
    head: Sequence[int] = (512, 256)
    dropout: float = 0.3
    axis_name: str | None = None    # data-parallel batch axis of the batch norms

    @nn.compact
    def __call__(self, points, train: bool = False):
        x = PointNetEncoder(self.features, self.axis_name)(points, train)
        for width in self.head:
            x = nn.relu(nn.BatchNorm(use_running_average=not train,
                                              axis_name=self.axis_name)(nn.Dense(width)(x)))
            x = nn.Dropout(self.dropout, deterministic=not train)(x)
        return ClassifyOut(nn.Dense(self.n_classes)(x))


def loss(out: ClassifyOut, batch, config):
    labels = batch["labels"]
    ce = jnp.mean(optax.softmax_cross_entropy_with_integer_labels(out.logits, labels))
    return ce, {"accuracy": jnp.mean(jnp.argmax(out.logits, -1) == labels)}


def _build(config):
    return PointNetClassifier(n_classes=config.n_classes, **dict(config.model_kwargs))


SPEC = ModelSpec(kind="classify", module=PointNetClassifier, outputs=ClassifyOut, loss=loss,
                 inputs=lambda batch: batch["points"], input_key="points", labelled=True,
                 build=_build)
