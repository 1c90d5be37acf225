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


def _moved(t, p):
    return p @ t[:3, :3].T + t[:3, 3]


def test_the_rival_is_the_chance_level_of_the_wrong_matches():
    """60 right matches among 500 random ones: the best other transform explains a handful, far
    below the right one's 60."""
    src, dst, t = _known(3, 560)
    dst[60:] = np.random.default_rng(4).uniform(-3, 3, size=(500, 3))
    t_est, inliers = estimation.ransac_consensus(dst, src, max_distance=0.05, seed=0)
    rival = estimation.rival_consensus(dst, src, t_est, max_distance=0.05, same_distance=0.3)
    assert inliers == 60 and rival < 10, (inliers, rival)


def test_a_second_transform_is_the_rival_and_t_itself_is_not():
    """Matches consistent with a second transform (a symmetric structure's other pose) are the
    rival; matches that agree with t only loosely (just outside twice the distance) are t again
    and skipped."""
    src, dst, t = _known(5, 200)
    other = np.eye(4)
    other[:3, :3] = augment.random_rotations(np.random.default_rng(6))
    dst[120:] = _moved(other, src[120:])                   # 80 for a second transform
    t_est, inliers = estimation.ransac_consensus(dst, src, max_distance=0.05, seed=0)
    assert inliers == 120
    rival = estimation.rival_consensus(dst, src, t_est, max_distance=0.05, same_distance=0.3)
    assert rival == 80
    loose = np.random.default_rng(7).normal(size=(80, 3))
    dst[120:] = _moved(t, src[120:]) + 0.12 * loose / np.linalg.norm(loose, axis=1)[:, None]
    t_est, _ = estimation.ransac_consensus(dst, src, max_distance=0.05, seed=0)
    assert estimation.rival_consensus(dst, src, t_est, max_distance=0.05,
                                      same_distance=0.3) < 10
