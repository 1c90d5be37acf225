"""Rotation-invariant classification: PointNet (no T-nets) on shapes oriented by Compass
(thesis 3.3). Trained on canonical-pose shapes; tested in canonical pose (NR) and under
arbitrary rotations (AR).

    python -m experiments.train --config=classify:cpu --workdir=runs/classify_cpu

Expected: on the embedded 12-class shape set, canonical-pose accuracy well above chance
(1/12) within the 'cpu' budget.
"""
from configs import common


def get_config(arg=None):
    size = common.check_size(arg)
    c = common.base(size)
    c.model = "classify"
    c.data.n_points = {"paper": 2048, "cpu": 512, "tiny": 64}[size]
    c.data.rotate = False            # train in canonical pose
    c.train.batch_size = {"paper": 32, "cpu": 16, "tiny": 4}[size]
    c.model_kwargs = {
        "paper": dict(features=(64, 64, 64, 128, 1024), head=(512, 256)),
        "cpu": dict(features=(64, 64, 128, 256), head=(128, 64)),
        "tiny": dict(features=(8, 8, 16), head=(8,)),
    }[size]
    return c
