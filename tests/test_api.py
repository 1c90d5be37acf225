"""The inference API: bundles orient and describe in chunks, concurrently, with clear errors
(model equivariance is tested per model in tests/models/)."""
import jax
import numpy as np
import pytest

from configs import lead, sound
import sphere_jax
from sphere_jax import api, models, training


def test_bundle_api_shapes_chunks_and_errors(tmp_path):
    config = sound.get_config("tiny")
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    variables = model.init(jax.random.PRNGKey(0), x * 0.3)
    state = {"params": variables["params"], "batch_stats": variables["batch_stats"]}
    training.save_bundle(str(tmp_path), config, state)
    bundle = api.load_bundle(tmp_path / "bundle")
    cloud = np.random.default_rng(1).uniform(-1, 1, (3000, 3)).astype(np.float32)
    kp = np.arange(7)
    d1 = bundle.describe(cloud, kp, radius=0.5, chunk=3, workers=1)
    d2 = bundle.describe(cloud, kp, radius=0.5, chunk=256)
    assert d1.shape == (7, 512) and np.allclose(d1, d2, atol=1e-5)
    # Concurrent chunks: same rows, same order, bit for bit (the last chunk is padded).
    assert np.array_equal(bundle.describe(cloud, kp, radius=0.5, chunk=3, workers=3), d1)
    assert bundle.orient(cloud, cloud[:5], radius=0.5).shape == (5, 3, 3)   # by coordinates
    with pytest.raises(ValueError, match="at least 16 points; got 1 of 1"):
        bundle.orient(np.concatenate([cloud, [[9.0, 9.0, 9.0]]]), [3000], radius=0.5)
    with pytest.raises(sphere_jax.SphereJaxError, match="not a bundle"):
        api.load_bundle(tmp_path)
    from sphere_jax import paths
    for kind in paths.SHIPPED:                  # shipped bundles by kind: the same folder
        assert api.bundle_path(kind) == paths.shipped_bundle(kind, required=True)
        assert api.load_bundle(kind).kind == kind.replace("_shapes", "")
    lead_config = lead.get_config("tiny")
    with pytest.raises(ValueError, match="of kind compass, sound to orient"):
        api.Bundle(models.build(lead_config), {}, lead_config).orient(cloud, kp)


def test_run_chunked_order_padding_and_workers():
    calls = []

    def fn(x):
        calls.append(len(x))
        return x * 2

    x = np.arange(10, dtype=np.float32)[:, None]
    for workers in (1, 2, 4):
        calls.clear()
        out = api.run_chunked(fn, x, 4, workers)
        assert np.array_equal(out, x * 2) and calls == [4, 4, 4]     # padded to one shape
    assert api.run_chunked(fn, x[:0], 4).shape == (0,)
    assert api.default_workers() >= 1
    with pytest.raises(ValueError, match="workers must be a positive integer; got 0"):
        api.run_chunked(fn, x, 4, workers=0)
    with pytest.raises(ValueError, match="chunk must be a positive integer; got 0"):
        api.run_chunked(fn, x, 0)
