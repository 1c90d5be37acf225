"""Hand-crafted descriptors: vectorised code vs loops, and rotation invariance on real data."""
import numpy as np
import pytest

from sphere_jax.data import augment
from sphere_jax.eval import pair_sets
from sphere_jax.features import descriptors, lrfs
from sphere_jax.features.neighbourhood import radius_neighbourhoods
from sphere_jax.registration.fragments import Fragment, estimate_normals
from tests import reference
from tests.eval import _fixtures


@pytest.fixture(scope="module")
def kitchen_fragment():
    pair_set = _fixtures.kitchen_or_embedded()
    return pair_sets.prepare(pair_set, pair_set.pairs[0][0], voxel=0.02, n_keypoints=300)


def _supports(f, k):
    """Float64 points, the first ``k`` keypoints, their 0.3 m neighbourhoods and SHOT LRFs."""
    pts = f.points.astype(np.float64)
    kp = f.keypoints[:k]
    nb = radius_neighbourhoods(pts, pts[kp], 0.3)
    return pts, kp, nb, lrfs.shot_lrf(nb)


def test_shot_and_spin_match_loop_reference(kitchen_fragment):
    f = kitchen_fragment
    pts, kp, nb, frames = _supports(f, 12)
    shot = descriptors.shot(nb, f.normals, frames)
    spin = descriptors.spin_image(nb, f.normals[kp])
    assert shot.shape == (12, 352) and spin.shape == (12, 153)
    for k in range(12):
        ref = reference.shot_loop(pts, f.normals.astype(np.float64), pts[kp[k]], 0.3, frames[k])
        np.testing.assert_allclose(shot[k], ref, atol=2e-6)
        ref = reference.spin_image_loop(pts, f.normals[kp[k]].astype(np.float64), pts[kp[k]],
                                        0.3)
        np.testing.assert_allclose(spin[k], ref, atol=2e-6)


def test_usc_matches_loop_reference(kitchen_fragment):
    f = kitchen_fragment
    pts, kp, nb, frames = _supports(f, 6)
    usc = descriptors.usc(nb, pts, frames)
    assert usc.shape == (6, descriptors.USC_DIM) and descriptors.USC_DIM == 1960
    for k in range(6):
        ref = reference.usc_loop(pts, pts[kp[k]], 0.3, frames[k])
        np.testing.assert_allclose(usc[k], ref, atol=2e-6)


def test_handcrafted_descriptors_are_rotation_invariant(kitchen_fragment):
    """The whole fragment turned about the sensor: FPFH, SHOT and Spin Images barely move
    (normals near grazing angles may flip when re-estimated, hence the percentile bound)."""
    f = kitchen_fragment
    rot = augment.random_rotations(np.random.default_rng(5))
    g = Fragment(f.key, (f.points @ rot.T).astype(np.float32), None, f.keypoints, None)
    from sklearn.neighbors import KDTree
    g.normals, g.tree = estimate_normals(g.points), KDTree(g.points)
    other = np.roll(f.keypoints, 1)                   # different keypoints: the chance level
    for name, fn in [
            ("fpfh", lambda fr, kp: descriptors.fpfh(fr.points, fr.normals, kp, 0.15)),
            ("shot", lambda fr, kp: descriptors.shot(
                radius_neighbourhoods(fr.points, fr.points[kp], 0.3), fr.normals)),
            ("spin", lambda fr, kp: descriptors.spin_image(
                radius_neighbourhoods(fr.points, fr.points[kp], 0.3), fr.normals[kp])),
            ("usc", lambda fr, kp: descriptors.usc(
                radius_neighbourhoods(fr.points, fr.points[kp], 0.3), fr.points))]:
        a, b, c = fn(f, f.keypoints), fn(g, g.keypoints), fn(f, other)
        same = np.linalg.norm(a - b, axis=1)
        chance = np.median(np.linalg.norm(a - c, axis=1))
        print(f"{name}: rotated median {np.median(same):.2e}, 95th pct "
              f"{np.percentile(same, 95):.3f}, different keypoints {chance:.3f}")
        assert np.median(same) < 0.05 * chance
        assert np.percentile(same, 95) < 0.25 * chance
