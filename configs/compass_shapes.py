"""Compass on whole shapes: the canonical-orientation network of the rotation-invariant
classification experiment (thesis 3.3). Each shape is one patch (centred on its bounding box,
radius half its largest side; 2048 points at 'paper' size), trained with Compass's
self-supervised loss on the embedded shape set (or any ModelNet40 folder).

    python -m experiments.train --config=compass_shapes:small --workdir=runs/compass_shapes_small

Expected: the geodesic loss falls well below its ~2 rad start within the 'small' budget; the
bundle then orients shapes for ``--config=classify``.
"""
from configs import compass


def get_config(arg=None):
    c = compass.get_config(arg)
    c.data.shapes = True
    c.data.root = ""           # '': the embedded shape set; or a ModelNet40 folder
    c.data.n_points = {"paper": 2048, "mid": 1024, "small": 512, "tiny": 64}[c.size]
    c.data.holdout_every = 0   # k > 0: as in ``classify``, each k-th shape is kept for testing
    if c.size == "mid":        # not Compass's scan recipe: the seed's channels, whole shapes
        c.model_kwargs.features = (40, 20, 10, 1)
        c.train.update(steps=20_000, batch_size=8, schedule="constant", warmup_steps=0,
                       final_lr_fraction=1.0)
    return c
