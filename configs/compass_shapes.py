"""Compass on whole shapes: the canonical-orientation network of the rotation-invariant
classification experiment (thesis 3.3). Each shape is one patch (centred on its centroid, radius
its farthest point: both turn with the shape; 2048 points at 'paper' size), trained with
Compass's self-supervised loss on the training part of a shape set (``ShapeSource``'s splits: the
classifiers test on shapes it never saw). 'mid' is the shipped bundle's recipe: the whole
ModelNet40 train release of the real data (PointNet's HDF5, 1024 points a shape); the other
sizes train on the embedded shape set.

    python -m experiments.train --config=compass_shapes:mid --workdir=runs/compass_shapes_mid

Expected: the geodesic loss falls well below its ~2 rad start within the 'small' budget; the
bundle then orients shapes for ``--config=classify``.
"""
from configs import common, compass


def get_config(arg=None):
    c = compass.get_config(arg)
    c.data.shapes = True
    c.data.root = ""           # '': the embedded shape set; or a ModelNet40 folder
    c.data.n_points = {"paper": 2048, "mid": 1024, "small": 512, "tiny": 64}[c.size]
    common.shape_splits(c)
    if c.size == "mid":        # not Compass's scan recipe: the seed's channels, whole shapes
        c.data.update(root=common.MODELNET_TRAIN, root_weights="")
        c.model_kwargs.features = (40, 20, 10, 1)
        c.train.update(steps=10_000, batch_size=8, learning_rate=1e-3,
                       schedule="warmup_cosine", warmup_steps=200, final_lr_fraction=0.01,
                       eval_batches=32)   # 256 validation shapes: a steadier angle
    return c
