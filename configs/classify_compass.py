"""Compass + PointNet (thesis 3.3): PointNet on shapes turned into the frames of the shipped
whole-shape Compass (each shape oriented once, data/oriented.py), trained in canonical pose —
rotation invariant by the frame alone.

    python -m experiments.train --config=classify_compass:mid --workdir=runs/classify_compass

'mid' is the recipe of the shipped bundle ``compass_pointnet_mid``; the NR/AR table is
``python -m experiments.evaluate --config=eval_classification:mid``.
"""
from configs import classify


def get_config(arg=None):
    c = classify.get_config(arg)
    c.orient_bundle = "compass_shapes"    # the shipped whole-shape Compass, or a bundle folder
    return c
