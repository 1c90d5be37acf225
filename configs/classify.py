"""Shape classification with PointNet (no T-nets), the classifier of the rotation-invariant
classification experiment (thesis 3.3), trained on canonical-pose shapes.

    python -m experiments.train --config=classify:small --workdir=runs/classify_small
    python -m experiments.train --config=classify:small \
        --config.orient_bundle=runs/compass_shapes_small/bundle

With ``orient_bundle`` (a whole-shape Compass, ``--config=compass_shapes``) every shape is
turned to its Compass frame first. Expected on the embedded 12-class shape set: validation
accuracy well above chance (1/12). The NR/AR comparison of plain and Compass-oriented PointNet
is the evaluation ``--config=eval_classification`` (``python -m experiments.evaluate``).
"""
from configs import common


def get_config(arg=None):
    size = common.check_size(arg)
    c = common.base(size)
    c.model = "classify"
    c.orient_bundle = ""              # a whole-shape Compass bundle: shapes in its frames
    c.data.root = ""                 # the embedded shape set, or a ModelNet40 folder
    c.data.n_points = {"paper": 2048, "mid": 1024, "small": 512, "tiny": 64}[size]
    c.data.rotate = False            # train in canonical pose
    c.data.holdout_every = 0         # k > 0: a set without test list tests on each k-th shape
    c.train.batch_size = {"paper": 32, "mid": 32, "small": 16, "tiny": 4}[size]
    c.model_kwargs = {
        "paper": dict(features=(64, 64, 64, 128, 1024), head=(512, 256)),
        "mid": dict(features=(64, 64, 64, 128, 512), head=(256, 128)),
        "small": dict(features=(64, 64, 128, 256), head=(128, 64)),
        "tiny": dict(features=(8, 8, 16), head=(8,)),
    }[size]
    return c
