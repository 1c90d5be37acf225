"""The boundary checks: every malformed argument is refused with an error of the project that
names the argument, what was expected and what came."""
import importlib

import jax
import ml_collections
import numpy as np
import pytest

import configs
import sphere_jax
from sphere_jax import checks
from sphere_jax.spherical import so3

CLOUD = np.random.default_rng(0).uniform(-1, 1, (50, 3)).astype(np.float32)


@pytest.mark.parametrize("points, message", [
    (np.zeros((0, 3)), "points must be a non-empty cloud"),
    (np.zeros(3), r"points must be a float array \[N, 3\]; got an array of shape \(3,\)"),
    (np.zeros((4, 2)), r"shape \(4, 2\)"),
    (np.array([[0, 0, np.nan], [0, 0, 1]]), "1 non-finite point"),
    (np.array([[0, 0, np.inf]] * 3), "3 non-finite point.*first at row 0"),
    (np.zeros((4, 3), bool), "dtype bool"),
    (np.array([["a", "b", "c"]]), "dtype <U1"),
    ([[0, 0], [1]], "list that is not an array"),
])
def test_bad_clouds(points, message):
    with pytest.raises(checks.InputError, match=message):
        checks.cloud(points)


def test_clouds_from_open3d_and_lists():
    import open3d as o3d
    legacy = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(CLOUD.astype(np.float64)))
    tensor = o3d.t.geometry.PointCloud(o3d.core.Tensor(CLOUD))
    for c in (legacy, tensor, CLOUD.tolist()):
        out = checks.cloud(c)
        assert out.dtype == np.float32 and np.allclose(out, CLOUD)


@pytest.mark.parametrize("kp, message", [
    (np.zeros(50, bool), "a boolean mask of shape \\(50,\\) \\(pass np.flatnonzero"),
    (np.array([0.0, 3.0]), r"integer indices \[K\] into points or float coordinates \[K, 3\]; "
                           r"got an array of shape \(2,\) and dtype float64"),
    (np.array([0.1, 0.2, 0.3]), r"shape \(3,\)"),                  # one coordinate, unbatched
    (np.zeros((4, 2)), r"shape \(4, 2\)"),
    (np.zeros((4, 3), np.int64), r"shape \(4, 3\) and dtype int64"),
    (np.array([0, 50]), r"indices in 0..49 \(points has 50\); got indices from 0 to 50"),
    (np.array([-1]), "from -1"),
    (np.array([[0.0, np.nan, 0.0]]), "1 non-finite row"),
])
def test_bad_keypoints(kp, message):
    with pytest.raises(checks.InputError, match=message):
        checks.keypoints(kp, len(CLOUD))


def test_keypoint_forms():
    idx, coords = checks.keypoints([3, 1], 50)
    assert coords is None and idx.tolist() == [3, 1] and idx.dtype == np.int64
    idx, coords = checks.keypoints(CLOUD[:2].astype(np.float64), 50)
    assert idx is None and coords.dtype == np.float32 and coords.shape == (2, 3)
    assert checks.keypoints([], 50)[0].shape == (0,)


@pytest.mark.parametrize("value, integer, message", [
    (0, False, "radius must be a positive finite number; got 0"),
    (-0.3, False, "got -0.3"),
    (float("nan"), False, "got nan"),
    (True, False, "positive number; got True"),
    ("0.3", False, "got str '0.3'"),
    (2.0, True, "radius must be a positive integer; got 2.0"),
    (0, True, "positive integer; got 0"),
])
def test_bad_positive_numbers(value, integer, message):
    with pytest.raises(checks.InputError, match=message):
        checks.positive(value, "radius", integer=integer)


def test_given_numbers_are_never_replaced_by_defaults():
    assert checks.positive(None, "radius", default=0.3) == 0.3
    assert checks.positive(0.1, "radius", default=0.3) == 0.1
    assert checks.positive(np.int64(3), "chunk", integer=True) == 3


def test_rotations():
    good = np.asarray(so3.random_rotation(jax.random.PRNGKey(0), (4,)), np.float64)
    assert np.allclose(checks.rotations(good, 4), good, atol=1e-6)
    cases = [(np.zeros((4, 3, 3)), "4 frame.*not.*det = 0"),
             (np.full((4, 3, 3), np.nan), "4 non-finite frame"),
             (good * np.array([1, 1, -1]), r"det = -1"),
             (good * 1.01, r"\|FᵀF − I\| = 0.02"),
             (good[:3], r"rotations \[4, 3, 3\] \(one per keypoint\); got an array of shape "
                        r"\(3, 3, 3\)")]
    for frames, message in cases:
        with pytest.raises(checks.InputError, match=message):
            checks.rotations(frames, 4)


@pytest.mark.parametrize("field, value, message", [
    ("train.steps", -5, "config.train.steps must be an integer >= 1; got -5"),
    ("train.learning_rate", float("nan"), "learning_rate must be a finite number > 0; got nan"),
    ("train.batch_size", 0, "batch_size must be an integer >= 1; got 0"),
    ("data.max_pairs", -1, r"max_pairs must be an integer >= 0 \(0: every pair\); got -1"),
    ("data.radius", 0.0, "radius must be a finite number > 0; got 0.0"),
    ("data.val_fraction", 1.0, "val_fraction must be a finite number >= 0 and below 1"),
    ("data.voxel", "2cm", "voxel must be a finite number > 0; got '2cm'"),
    ("rho", 2.0, "config.rho must be a finite number > 0 and at most 1; got 2.0"),
    ("tau1", -0.1, "config.tau1 must be a finite number > 0; got -0.1"),
    ("match_dist", float("nan"), "config.match_dist must be a finite number > 0; got nan"),
])
def test_config_values(field, value, message):
    *section, name = field.split(".")
    config = {name: value} if not section else {section[0]: {name: value}}
    with pytest.raises(checks.ConfigError, match=message):
        checks.config_values(ml_collections.ConfigDict(config))


def test_shipped_configs_pass_their_checks():
    from configs import eval_registration, lead
    for size in ("paper", "mid", "small", "tiny"):
        checks.config_values(lead.get_config(size))
    checks.config_values(eval_registration.get_config("quick"))
    for name in configs.config_names():             # every experiment's default arguments
        module = importlib.import_module(f"configs.{name}")
        checks.config_values(module.get_config("tiny"))
    assert checks.config_values(ml_collections.ConfigDict({"chunk": None}))   # a placeholder


def test_one_base_class_catches_every_refusal(tmp_path):
    from sphere_jax.data.readers import io
    errors = [lambda: checks.cloud([]), lambda: io.read_points(tmp_path / "no.ply"),
              lambda: sphere_jax.load_bundle(tmp_path),
              lambda: checks.config_values(ml_collections.ConfigDict({"chunk": 0}))]
    for make in errors:
        with pytest.raises(sphere_jax.SphereJaxError):
            make()
    assert issubclass(sphere_jax.SphereJaxError, ValueError)
    assert issubclass(checks.MissingError, FileNotFoundError)


def test_bundle_arguments_and_empty_tensor_clouds_get_our_errors():
    import open3d as o3d


    pts = np.random.default_rng(0).random((100, 3)).astype(np.float32)
    for bad in (None, 3):
        with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be a Bundle, a bundle "
                                                            "folder or a shipped model kind"):
            sphere_jax.orient(bad, pts, [0])
    with pytest.raises(sphere_jax.SphereJaxError, match="points must be a non-empty cloud"):
        checks.cloud(o3d.t.geometry.PointCloud())
