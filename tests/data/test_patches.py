
import numpy as np
import pytest

from sphere_jax.data import augment, patches
from tests.eval import _fixtures


def test_patches_are_local_fixed_size_and_exclude_the_keypoint():
    rng = np.random.default_rng(0)
    cloud = rng.uniform(-1, 1, (5000, 3)).astype(np.float32)
    kp = patches.random_keypoints(cloud, 50, rng)
    out = patches.extract_patches(cloud, kp, 0.3, 256, rng, min_points=10)
    assert out.points.shape == (len(out.keypoints), 256, 3)
    r = np.linalg.norm(out.points, axis=-1)
    assert r.max() <= 0.3 + 1e-6 and r.min() > 0
    # Sampling is uniform over the neighbours: each neighbour is drawn about equally often.
    big = patches.extract_patches(cloud, kp[:1], 0.3, 200_000, rng)
    _, counts = np.unique(big.points[0], axis=0, return_counts=True)
    assert len(counts) == big.counts[0] and counts.std() / counts.mean() < 0.2


def _multiplicities(support_Nx3, patch_Nx3):
    """How often each support point appears in a patch drawn from it."""
    index = {tuple(p): i for i, p in enumerate(support_Nx3)}
    return np.bincount([index[tuple(p)] for p in patch_Nx3], minlength=len(support_Nx3))


def test_even_draws_take_every_support_point_as_often_as_the_count_allows():
    """'even': with c support points and N >= c draws each point comes N // c or N // c + 1
    times (random draws leave some out and repeat others); with N < c, N distinct points."""
    rng = np.random.default_rng(3)
    cloud = rng.uniform(-1, 1, (400, 3)).astype(np.float32)
    centre = np.zeros((1, 3), np.float32)
    support = cloud[np.linalg.norm(cloud, axis=1) <= 0.8]
    c = len(support)
    for n in (c, 3 * c + 7):
        got = patches.patches_around(cloud, centre, 0.8, n, rng, draw="even")
        m = _multiplicities(support, got.points[0])
        assert m.min() == n // c and m.max() <= n // c + 1 and m.sum() == n
        noisy = _multiplicities(support, patches.patches_around(
            cloud, centre, 0.8, n, rng).points[0])
        assert noisy.max() - noisy.min() >= 2
    few = patches.patches_around(cloud, centre, 0.8, c // 3, rng, draw="even").points[0]
    assert len(np.unique(few, axis=0)) == c // 3
    with pytest.raises(ValueError, match="draw must be one of 'random', 'even'"):
        patches.patches_around(cloud, centre, 0.8, 8, rng, draw="grid")


def test_min_points_drops_sparse_supports():
    cloud = np.concatenate([np.random.default_rng(1).normal(size=(500, 3)) * 0.05,
                            [[5.0, 5.0, 5.0], [5.01, 5.0, 5.0]]]).astype(np.float32)
    out = patches.extract_patches(cloud, [0, 500], 0.2, 64, np.random.default_rng(0),
                                  min_points=100)
    assert out.keypoints.tolist() == [0]


def test_voxel_and_uniform_keypoints():
    rng = np.random.default_rng(2)
    cloud = rng.uniform(0, 1, (20000, 3))
    down = patches.voxel_downsample(cloud, 0.1)
    assert len(down) == 1000
    kp = patches.uniform_keypoints(cloud, 0.25)
    cells = np.floor(cloud[kp] / 0.25).astype(int)
    assert len(kp) == 64 and len(np.unique(cells, axis=0)) == 64


def test_scan_fragment_5000_patches():
    """On the real kitchen fragment, or an embedded room fragment on a fresh clone."""
    pts = _fixtures.kitchen_or_embedded().load(0)
    rng = np.random.default_rng(0)
    out = patches.extract_patches(pts, patches.random_keypoints(pts, 5000, rng), 0.3, 1225, rng,
                                  min_points=300)
    assert out.points.shape[1:] == (1225, 3) and len(out.keypoints) > 4000
    assert len(patches.iss_keypoints(pts, 0.1, 0.1)) > 20


def test_bad_inputs():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="points must be"):
        patches.extract_patches(np.zeros((5, 2)), [0], 0.1, 8, rng)
    with pytest.raises(ValueError, match="non-finite"):
        patches.voxel_downsample(np.array([[0, 0, np.nan]]), 0.1)
    with pytest.raises(ValueError, match=r"keypoints must be indices in 0..4 \(points has 5\); "
                                         r"got indices from 7"):
        patches.extract_patches(np.zeros((5, 3)), [7], 0.1, 8, rng)
    with pytest.raises(ValueError, match="points must be a non-empty cloud"):
        patches.uniform_keypoints(np.zeros((0, 3)), 0.1)


def test_augmentations_are_seeded_and_do_what_they_say():
    rng = np.random.default_rng(3)
    rots = augment.random_rotations(rng, 4000)
    assert np.allclose(np.linalg.det(rots), 1) and np.abs(rots.mean(0)).max() < 0.03
    patch = np.random.default_rng(4).normal(size=(1225, 3)) * 0.1
    kept = [len(augment.occlude(patch, 0.3, np.random.default_rng(s))) for s in range(400)]
    untouched = np.mean(np.array(kept) == 1225)
    assert 0.4 < untouched < 0.6                                       # p_none = 0.5
    removed = 1225 - np.array([k for k in kept if k < 1225])
    assert removed.min() >= 0.05 * 1225 - 1 and removed.max() <= 0.20 * 1225 + 1
    a = augment.occlude(patch, 0.3, np.random.default_rng(9))
    b = augment.occlude(patch, 0.3, np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)
    assert len(augment.change_density(patch, 0.5, rng)) == 612
    assert abs(np.std(augment.jitter(patch, 0.01, rng) - patch) - 0.01) < 1e-3
