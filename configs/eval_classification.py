"""Rotation-invariant classification (thesis 3.3): PointNet alone and on shapes oriented by
Compass, both trained on canonical-pose shapes, tested in canonical pose (NR) and with every
test shape turned by a seeded random rotation (AR).

    python -m experiments.evaluate --config=eval_classification:small
    python -m experiments.evaluate --config=eval_classification:small \
        --config.data.root=/data/modelnet40_normal_resampled

Trains one PointNet per method (``workdir/<method>/``, the ``classify`` config at this size),
then writes classification.csv (method, split, accuracy) and classification.md. What it
measures: whether orienting shapes by Compass makes a classifier trained in canonical pose
as accurate on rotated shapes (AR) as on canonical ones (NR); plain PointNet loses most of
its accuracy in AR. ModelNet40's 102 / 25 split of ``../shared/data``:
``--config.data.holdout_every=3``. The Compass bundle is the shipped whole-shape one
(``--config=compass_shapes``), or ``--config.compass_bundle=PATH``.

``--config.compass_train_rotated=True`` trains Compass + PointNet on randomly turned shapes
instead (oriented by Compass like the test shapes); off by default.
"""
from configs import classify
from sphere_jax import paths


def get_config(arg=None):
    c = classify.get_config(arg)
    c.task = "classification"
    c.methods = "pointnet,compass+pointnet"
    c.compass_bundle = paths.shipped_bundle("compass_shapes")
    c.compass_train_rotated = False   # True: Compass + PointNet trains on randomly turned shapes
    c.eval_rotation_seed = 0          # AR split: one seeded rotation per test shape
    c.rotate = False                  # no rotated variant of this benchmark (it has AR)
    return c
