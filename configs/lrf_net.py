"""A learned x̂ on the support's normal (LRF-Net's design; sphere_jax/models/lrf_net.py),
trained like the shipped Compass: on the clean real scans, a rotated and occluded copy of
each patch, the geodesic loss between the two frames.

    python -m experiments.train --config=lrf_net:mid --workdir=runs/lrf_net_mid

Measures whether a frame whose ẑ is the normal (which repeats where Compass's ẑ does not) and
whose x̂ is learned repeats more often than Compass's: LRF repeatability on the validation
pairs of ``make_data --validation`` (chosen there; docs/training.md), reported on redkitchen
and the bunny.
"""
from configs import common, compass_real


def get_config(arg=None):
    size = common.check_size(arg)
    c = compass_real.get_config(size)
    c.model = "lrf_net"
    c.model_kwargs = {
        "paper": dict(point=(64, 128), score=(128, 64)),
        "mid": dict(point=(32, 64), score=(64, 32)),
        "small": dict(point=(16, 32), score=(32, 16)),
        "tiny": dict(point=(8, 8), score=(8, 8)),
    }[size]
    if size == "mid":
        c.train.update(steps=6000, batch_size=32, learning_rate=1e-3)
    return c
