"""Hand-crafted LRFs: vectorised code vs per-keypoint loops, frame properties, invariance."""
import numpy as np
import pytest

from sphere_jax.data import augment, patches
from sphere_jax.features import lrfs
from sphere_jax.features.neighbourhood import radius_neighbourhoods
from sphere_jax.registration import fragments
from tests import reference
from tests.eval import _fixtures


@pytest.fixture(scope="module")
def kitchen_points():
    return patches.voxel_downsample(_fixtures.kitchen_or_embedded().load(0), 0.02)


@pytest.fixture(scope="module")
def kitchen_normals(kitchen_points):
    return fragments.estimate_normals(kitchen_points.astype(np.float64))


def _lrf(name, nb, normals):
    fn = getattr(lrfs, f"{name}_lrf")
    return fn(nb, normals) if name == "gframes" else fn(nb)


@pytest.mark.parametrize("name", ["shot", "toldi", "threedsn", "gframes"])
def test_matches_loop_reference_on_scan_points(kitchen_points, kitchen_normals, name):
    pts = kitchen_points.astype(np.float64)
    kp = np.random.default_rng(0).choice(len(pts), 20, replace=False)
    nb = radius_neighbourhoods(pts, pts[kp], 0.3)
    fast = _lrf(name, nb, kitchen_normals)
    loop = getattr(reference, f"{name}_lrf_loop")
    slow = np.stack([loop(pts, kitchen_normals, pts[k], 0.3) if name == "gframes" else
                     loop(pts, pts[k], 0.3) for k in kp])
    assert np.max(np.abs(fast - slow)) < 1e-9


@pytest.mark.parametrize("name", ["shot", "toldi", "threedsn", "gframes"])
def test_frames_are_rotations_and_rotate_with_the_cloud(kitchen_points, kitchen_normals, name):
    pts = kitchen_points.astype(np.float64)
    kp = np.random.default_rng(1).choice(len(pts), 500, replace=False)
    rot = augment.random_rotations(np.random.default_rng(2))
    f = _lrf(name, radius_neighbourhoods(pts, pts[kp], 0.3), kitchen_normals)
    g = _lrf(name, radius_neighbourhoods(pts @ rot.T, pts[kp] @ rot.T, 0.3),
             kitchen_normals @ rot.T)
    ok = np.all(np.isfinite(f), axis=(1, 2))
    assert ok.mean() > 0.99
    assert np.max(np.abs(np.einsum("kji,kjl->kil", f[ok], f[ok]) - np.eye(3))) < 1e-9
    assert np.min(np.linalg.det(f[ok])) > 0.999
    err = np.linalg.norm(rot @ f[ok] - g[ok], axis=(1, 2))
    assert np.median(err) < 1e-9
    assert np.mean(err < 1e-6) > 0.99       # rare ties in the sign votes may flip an axis


def test_too_few_neighbours_gives_nan_not_garbage():
    pts = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [5, 5, 5]], float)
    f = lrfs.shot_lrf(radius_neighbourhoods(pts, pts[[0, 3]], 0.1))
    assert np.isnan(f).all()
