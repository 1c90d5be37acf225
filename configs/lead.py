"""LEAD: an unsupervised rotation-equivariant descriptor (thesis 4.1).

    python -m experiments.train --config=lead:small --workdir=runs/lead_small
    python -m experiments.train --config=lead:mid --workdir=runs/lead_mid   # shipped size

Expected: the Chamfer loss (unit-ball patches) falls steadily; the 512-value descriptor is an
SO(3) map that rotates with the patch (tests check it).
"""
from configs import common


def get_config(arg=None):
    size = common.check_size(arg)
    c = common.base(size)
    c.model = "lead"
    c.train.batch_size = {"paper": 100, "mid": 32, "small": 16, "tiny": 4}[size]
    c.model_kwargs = {
        "paper": dict(bandwidths=(24, 16, 12, 8, 6, 4), features=(40, 40, 40, 40, 1)),
        # Table 4.5's F with the S2 layer ending at B = 8: SO(3) layers at input bandwidths
        # 8, 8, 6, 40 channels. The first pointwise step runs on the 16³ grid instead of 24³:
        # 0.123 GFLOP per patch against 0.190 (docs/performance.md, "What the architecture
        # costs"); 12000 steps took 127 min on the 2 cores.
        "mid": dict(bandwidths=(16, 8, 8, 6, 4), features=(40, 40, 40, 1)),
        "small": dict(bandwidths=(8, 6, 5, 4, 4, 4), features=(16, 16, 16, 16, 1)),
        "tiny": dict(bandwidths=(4, 4, 4, 4, 4, 4), features=(4, 4, 4, 4, 1)),
    }[size]
    c.model_kwargs.update(common.decoder_kwargs(size))
    if size == "mid":
        common.shipped_recipe(c, steps=12000, batch_size=32)
    return c
