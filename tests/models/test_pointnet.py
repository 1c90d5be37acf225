"""PointNet's encoder at inference (BN folded, one patch at a time) against a NumPy reference
of the layer-by-layer definition: Dense, batch norm with the running moments, ReLU, max pool."""
import jax
import numpy as np
import pytest

from sphere_jax.models import pointnet
from tests import reference


def _numpy_codes(variables, points, n_layers):
    params, stats = variables["params"], variables["batch_stats"]
    x = np.asarray(points, np.float64)
    for i in range(n_layers):
        d, n, m = params[f"Dense_{i}"], params[f"BatchNorm_{i}"], stats[f"BatchNorm_{i}"]
        x = x @ np.asarray(d["kernel"], np.float64) + np.asarray(d["bias"], np.float64)
        x = (x - np.asarray(m["mean"])) / np.sqrt(np.asarray(m["var"]) + pointnet.BN_EPSILON)
        x = np.maximum(x * np.asarray(n["scale"]) + np.asarray(n["bias"]), 0.0)
    return x.max(axis=-2)


def test_inference_codes_equal_the_layer_by_layer_definition():
    rng = np.random.default_rng(0)
    model = pointnet.PointNetEncoder(features=(16, 32, 48))
    points = rng.normal(size=(2, 5, 64, 3)).astype(np.float32)     # two leading batch axes
    variables = reference.init(model, points, train=False)
    # Moments and affine parameters away from their identity start, so that folding them in
    # is exercised (negative scales included: the max must still come after the bias).
    variables = jax.tree_util.tree_map(np.asarray, variables)
    for i in range(3):
        width = model.features[i]
        variables["batch_stats"][f"BatchNorm_{i}"] = {
            "mean": rng.normal(size=width).astype(np.float32),
            "var": rng.uniform(0.2, 3.0, width).astype(np.float32)}
        variables["params"][f"BatchNorm_{i}"] = {
            "scale": rng.normal(size=width).astype(np.float32),
            "bias": rng.normal(size=width).astype(np.float32)}
    got = np.asarray(reference.apply(model, variables, points, train=False))
    want = _numpy_codes(variables, points, 3)
    assert got.shape == (2, 5, 48)
    err = np.abs(got - want).max() / np.abs(want).max()
    assert err < 1e-5, err
    assert (want > 0).mean() > 0.3           # ReLU does not zero the codes wholesale


def test_inference_without_running_moments_is_refused_by_name():
    model = pointnet.PointNetEncoder(features=(8, 16))
    points = np.zeros((2, 10, 3), np.float32)
    variables = reference.init(model, points, train=False)
    with pytest.raises(ValueError, match="batch_stats"):
        model.apply({"params": variables["params"]}, points, train=False)
