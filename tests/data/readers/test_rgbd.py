"""RGB-D frames fuse under their camera-to-world poses."""
import os

import numpy as np
from sklearn.neighbors import NearestNeighbors

from sphere_jax.data.readers import rgbd


def test_rgbd_frames_fuse_under_their_poses(shared):
    root = os.path.join(shared, "rgbd/3dmatch_toolbox")
    k = rgbd.read_intrinsics(os.path.join(root, "camera-intrinsics.txt"))
    frame = lambda n: os.path.join(root, "rgbd-frames", f"frame-{n:06d}")
    clouds = [rgbd.read_rgbd_frame(frame(n) + ".color.png", frame(n) + ".depth.png", k,
                                       rgbd.read_pose(frame(n) + ".pose.txt"))
              for n in (8, 20)]
    d = NearestNeighbors(n_neighbors=1).fit(clouds[0].points).kneighbors(
        clouds[1].points[::7])[0]
    assert np.mean(d < 0.02) > 0.90
    assert clouds[0].colors.shape == clouds[0].points.shape and clouds[0].colors.max() <= 1
