import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sphere_jax import api, models
from sphere_jax.spherical import so3, transforms
from sphere_jax.data import augment, patches
from sphere_jax.data.readers import io

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COMPASS = os.path.join(REPO, "checkpoints", "compass_cpu", "bundle")


def test_lead_encoder_is_equivariant(capsys):
    """maps(R·P) vs L_R maps(P) for the same points: the whole encoder (signal, convolutions,
    batch norm, ReLU) commutes with rotations up to the grid's discretisation."""
    model = models.Lead(bandwidths=(8, 6, 5, 4, 4, 4), features=(8, 8, 8, 8, 1),
                        decoder_side=4, decoder_hidden=(8, 8, 8))
    rng = np.random.default_rng(0)
    uv = rng.uniform(-0.7, 0.7, (6, 2000, 2))
    a, b, c = (rng.normal(size=(6, 1, 1)) for _ in range(3))
    z = (0.3 * np.sin(3 * a * uv[..., :1]) + 0.3 * b * uv[..., 1:] ** 2
         + 0.2 * c * uv[..., :1] * uv[..., 1:])
    p = np.concatenate([uv, z], -1).astype(np.float32)              # 6 different surfaces
    variables = model.init(jax.random.PRNGKey(0), p)
    encode = jax.jit(lambda x: model.apply(variables, x, method="encode"))
    errs, unrelated = [], []
    base = encode(p)
    for seed in range(3):
        rot = np.asarray(so3.random_rotation(jax.random.PRNGKey(seed)))
        lhs = encode(p @ rot.T)
        rhs = jax.vmap(transforms.rotate_so3, (0, None))(base, rot)
        errs.append(float(jnp.linalg.norm(lhs - rhs) / jnp.linalg.norm(rhs)))
        # The same comparison against the other patches' descriptors, for scale.
        unrelated.append(float(jnp.linalg.norm(lhs - jnp.roll(rhs, 1, 0)) / jnp.linalg.norm(rhs)))
    with capsys.disabled():
        print(f"\n  LEAD encoder (B 8->4) equivariance, relative error: {np.round(errs, 3)}; "
              f"against other patches: {np.round(unrelated, 3)}")
    # Not exact: the patch signal is not band-limited and ReLU acts on the grid.
    assert max(errs) < 0.25 and max(errs) < min(unrelated) / 4


@pytest.mark.skipif(not os.path.isdir(COMPASS), reason="no shipped Compass bundle")
def test_shipped_compass_rotates_with_real_patches(shared, capsys):
    compass = api.load_bundle(COMPASS)
    results = {}
    for name, rel, radius in [("3DMatch kitchen", "3dmatch/7-scenes-redkitchen/cloud_bin_0.ply",
                               0.3),
                              ("bunny", "stanford/bunny/data/bun000.ply", 0.02)]:
        pts = io.read_points(os.path.join(shared, rel)).points
        if name == "bunny":
            pts = patches.voxel_downsample(pts, 0.001)
        kp = patches.random_keypoints(pts, 100, np.random.default_rng(0))
        frames = compass.orient(pts, kp, radius=radius)
        errs = []
        for seed in range(2):
            rot = augment.random_rotations(np.random.default_rng(seed)).astype(np.float32)
            rotated = compass.orient(pts @ rot.T, kp, radius=radius)
            errs.append(np.asarray(so3.geodesic_distance(rotated, rot @ frames)))
        results[name] = np.concatenate(errs)
    with capsys.disabled():
        for name, e in results.items():
            print(f"\n  Compass (cpu bundle) on {name}: geodesic error of F(RP) vs R F(P): mean "
                  f"{e.mean():.3f} rad, median {np.median(e):.3f} rad "
                  f"(random frames: ~2.2 rad)")
    for e in results.values():
        assert np.median(e) < 0.8 and e.mean() < 1.3


def test_bundle_api_shapes_chunks_and_errors(tmp_path):
    from configs import sound
    from sphere_jax import training
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
    with pytest.raises(ValueError, match="no neighbour"):
        bundle.orient(np.concatenate([cloud, [[9.0, 9.0, 9.0]]]), [3000], radius=0.5)
    with pytest.raises(FileNotFoundError, match="not a bundle"):
        api.load_bundle(tmp_path)


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
    with pytest.raises(ValueError, match="workers=0"):
        api.run_chunked(fn, x, 4, workers=0)
    with pytest.raises(ValueError, match="chunk=0"):
        api.run_chunked(fn, x, 0)
