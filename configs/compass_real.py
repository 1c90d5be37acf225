"""Compass trained on clean real scans only: 'mid' of configs/compass.py with the scans of
``training_scans/scans`` (PCL's Kinect and stereo frames, two laser scans of large rooms, a
ScanNet room, a SUN RGB-D frame) as three of every four batches' scans by weight and open3d's
fused RGB-D frames as the fourth; no synthetic room.

    python -m experiments.train --config=compass_real:mid --workdir=runs/compass_real_mid  # compass

Measures what real scans teach a learned frame that the generator's rooms do not: chosen over
rooms only and rooms + real scans on the validation pairs of ``make_data --validation``
(7-scenes-stairs, shelf-bin; docs/training.md), the LRF repeatability there and, to report,
on redkitchen and the bunny.
"""
from configs import common, compass

REAL_ONLY = "shared/training_scans/scans," + common.REAL_SCAN


def get_config(arg=None):
    c = compass.get_config(arg)
    if c.size == "mid":
        c.data.update(root=REAL_ONLY, root_weights="3,1")
    return c
