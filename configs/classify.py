"""Rotation-invariant classification: PointNet (no T-nets) alone and on shapes oriented by
Compass (thesis 3.3). Both are trained on canonical-pose shapes and tested in canonical pose
(NR) and under arbitrary rotations (AR).

    python -m experiments.train --config=classify:cpu --workdir=runs/classify_cpu
    python -m experiments.train --config=classify:cpu --config.data.root=/data/modelnet40_normal_resampled

Writes classification.csv (method, split, accuracy) and classification.md in the workdir, and
one trained bundle per method under it. Expected on the embedded 12-class shape set: plain
PointNet well above chance (1/12) in NR and close to chance in AR; Compass + PointNet about
as accurate in AR as in NR. The Compass bundle comes from ``--config=compass_shapes``.
"""
from configs import common
from sphere_jax import paths


def get_config(arg=None):
    size = common.check_size(arg)
    c = common.base(size)
    c.model = "classify"
    c.methods = "pointnet,compass+pointnet"
    c.orient_bundle = ""              # set per method by the experiment; see compass_bundle
    c.compass_bundle = paths.shipped_bundle("compass_shapes_cpu")
    c.eval_rotation_seed = 0          # AR split: one seeded rotation per test shape
    c.data.n_points = {"paper": 2048, "cpu": 512, "tiny": 64}[size]
    c.data.rotate = False            # train in canonical pose
    c.train.batch_size = {"paper": 32, "cpu": 16, "tiny": 4}[size]
    c.model_kwargs = {
        "paper": dict(features=(64, 64, 64, 128, 1024), head=(512, 256)),
        "cpu": dict(features=(64, 64, 128, 256), head=(128, 64)),
        "tiny": dict(features=(8, 8, 16), head=(8,)),
    }[size]
    return c
