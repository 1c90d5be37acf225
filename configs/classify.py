"""Shape classification with PointNet (no T-nets), the classifier of the rotation-invariant
classification experiment (thesis 3.3), trained in canonical pose without rotation augmentation.

    python -m experiments.train --config=classify:mid --workdir=runs/classify_mid   # shipped
    python -m experiments.train --config=classify:small --workdir=runs/classify_small

'mid' is the recipe of the shipped plain-PointNet bundle ``pointnet_mid``: the training part of
ModelNet40's train release (``ShapeSource``'s splits; validation on its own part). With
``orient_bundle`` (a whole-shape Compass; ``configs/classify_compass.py``) every shape is
turned into its Compass frame first. The NR/AR table is ``--config=eval_classification``
(``python -m experiments.evaluate``). Expected on the embedded 12-class shape set ('small'):
validation accuracy well above chance (1/12).
"""
from configs import common


def get_config(arg=None):
    size = common.check_size(arg)
    c = common.base(size)
    c.model = "classify"
    c.orient_bundle = ""              # a whole-shape Compass bundle: shapes in its frames
    c.data.root = common.MODELNET_TRAIN if size == "mid" else ""   # '': the embedded shapes
    c.data.n_points = {"paper": 2048, "mid": 1024, "small": 512, "tiny": 64}[size]
    c.data.rotate = False            # train in canonical pose
    common.shape_splits(c)
    c.train.batch_size = {"paper": 32, "mid": 32, "small": 16, "tiny": 4}[size]
    if size == "mid":                # the shipped bundle's recipe: ~25 epochs of 6299 shapes
        c.train.update(steps=5000, learning_rate=1e-3, schedule="warmup_cosine",
                       warmup_steps=200, final_lr_fraction=0.01, eval_batches=16)
    c.model_kwargs = {
        "paper": dict(features=(64, 64, 64, 128, 1024), head=(512, 256)),
        "mid": dict(features=(64, 64, 64, 128, 512), head=(256, 128)),
        "small": dict(features=(64, 64, 128, 256), head=(128, 64)),
        "tiny": dict(features=(8, 8, 16), head=(8,)),
    }[size]
    return c
