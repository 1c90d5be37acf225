"""Compass + PointNet trained on turned shapes (``compass_train_rotated`` in the results): each
training shape is turned by 8 seeded random rotations and each copy oriented by the shipped
whole-shape Compass, so the classifier learns the frames Compass gives turned shapes — its
mistakes and its choices among a symmetric shape's frames included.

    python -m experiments.train --config=classify_compass_rotated:mid \
        --workdir=runs/classify_compass_rotated

'mid' is the recipe of the shipped bundle ``compass_pointnet_rotated_mid``.
"""
from configs import classify_compass


def get_config(arg=None):
    c = classify_compass.get_config(arg)
    c.data.rotate = True
    return c
