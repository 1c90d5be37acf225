"""LEAD-PN: LEAD with a PointNet encoder on FLARE-oriented patches (ablation, thesis 4.1).

    python -m experiments.train --config=lead_pn:small --workdir=runs/lead_pn_small

Expected: the Chamfer loss falls faster than LEAD's at first (no spherical convolutions), but
the code depends on the FLARE frame's repeatability.
"""
from configs import common


def get_config(arg=None):
    size = common.check_size(arg)
    c = common.base(size)
    c.model = "lead_pn"
    c.train.batch_size = {"paper": 100, "mid": 32, "small": 16, "tiny": 4}[size]
    c.model_kwargs = {
        "paper": dict(features=(64, 128, 512)),
        "mid": dict(features=(64, 128, 512)),
        "small": dict(features=(64, 128, 512)),
        "tiny": dict(features=(8, 8, 16)),
    }[size]
    c.model_kwargs.update(common.decoder_kwargs(size))
    if size == "mid":
        common.shipped_recipe(c, steps=10000, batch_size=32)
    return c
