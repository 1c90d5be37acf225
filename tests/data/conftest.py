"""Fixtures of the data tests."""
import os

import pytest

from sphere_jax import paths
from sphere_jax.data.generators import synthetic


@pytest.fixture(scope="module")
def frames():
    """A posed RGB-D sequence: real Kinect frames (3DMatch toolbox) when present, else the
    embedded synthetic table-top frames (same layout)."""
    real = paths.real_data("rgbd", "3dmatch_toolbox", "rgbd-frames")
    if real and os.path.isdir(real):
        return real
    return synthetic.default_root("objects")
