"""Rotation-invariant classification (thesis 3.3): PointNet alone, on shapes oriented by
Compass, and Compass + PointNet trained on turned shapes, tested in canonical pose (NR) and
with every test shape turned by a seeded random rotation (AR).

    python -m experiments.evaluate --config=eval_classification:mid \
        --workdir=runs/classification_modelnet                     # the shipped classifiers
    python -m experiments.evaluate --config=eval_classification:small   # trains its own

At 'mid' it scores the shipped classifier bundles (``classify``, ``classify_compass``,
``classify_compass_rotated`` recipes) on the test split of ModelNet40's train release
(``ShapeSource``: every 5th shape of each class; the classifiers and the whole-shape Compass
never trained or chose a setting on it); at other sizes, or with
``--config.classifiers.<method>=''``, it trains the method's classifier in
``workdir/<method>`` with this config first. Writes classification.csv / .md (method, split,
accuracy, the thesis's figure) and frames.csv: per class, the share of test shapes whose
Compass frame turns with the shape (within 15°) and the AR accuracy on those and the rest.
"""
import ml_collections

from configs import classify
from sphere_jax.models import shipped

CLASSIFIERS = {"pointnet": "pointnet", "compass+pointnet": "compass_pointnet",
               "compass_train_rotated": "compass_pointnet_rotated"}


def get_config(arg=None):
    c = classify.get_config(arg)
    c.task = "classification"
    c.methods = "pointnet,compass+pointnet,compass_train_rotated"
    c.compass_bundle = "compass_shapes"   # the shipped whole-shape Compass, or a bundle folder
    # Each method's classifier bundle; '': train one here with this config.
    c.classifiers = ml_collections.ConfigDict(
        {m: (shipped.bundle_path(name) if c.size == "mid" else "")
         for m, name in CLASSIFIERS.items()})
    c.eval_rotation_seed = 0          # AR split: one seeded rotation per test shape
    c.rotate = False                  # no rotated variant of this benchmark (it has AR)
    return c
