"""Rigid estimation: Kabsch and RANSAC recover a known transform; RANSAC's consensus counts
the correspondences it explains."""
import numpy as np

from sphere_jax.data import augment
from sphere_jax.registration import estimation


def _known(seed=0, n=200):
    rng = np.random.default_rng(seed)
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = augment.random_rotations(rng), rng.normal(size=3)
    src = rng.uniform(-1, 1, size=(n, 3))
    return src, src @ t[:3, :3].T + t[:3, 3], t


def test_kabsch_recovers_a_rigid_transform():
    src, dst, t = _known()
    assert np.abs(estimation.kabsch(src, dst) - t).max() < 1e-9


def test_ransac_recovers_it_among_outliers_and_counts_the_inliers():
    src, dst, t = _known(1, 300)
    dst[:150] = np.random.default_rng(2).uniform(-3, 3, size=(150, 3))     # half are wrong
    t_est, inliers = estimation.ransac_consensus(dst, src, max_distance=0.05, seed=0)
    assert np.abs(t_est - t).max() < 1e-6
    assert inliers == 150
