"""Descriptor whitening: Mahalanobis distances against a NumPy reference, the null space
dropped, files round-trip, the API applies the right one, and on real scans it matches better."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from configs import sound
import sphere_jax
from sphere_jax import models, training
from sphere_jax.bundles import inference, model_card
from sphere_jax.features import whitening_fit
from sphere_jax.bundles import whitening
from sphere_jax.spherical import so3, transforms
from sphere_jax.models import shipped
from tests import reference


def _correlated(n=4000, d=6, rank=None, seed=0):
    rng = np.random.default_rng(seed)
    mix = rng.normal(size=(rank or d, d)) * np.logspace(0, -3, rank or d)[:, None]
    return rng.normal(size=(n, rank or d)) @ mix + rng.normal(size=d)


def test_whitened_distances_are_mahalanobis_distances():
    x = _correlated()
    w = whitening.fit(x, eps=0.0)
    inverse = np.linalg.inv(np.cov(x.T))
    a, b = x[:50], x[50:100]
    slow = np.sqrt(np.einsum("kd,de,ke->k", a - b, inverse, a - b))
    fast = np.linalg.norm(w.transform(a) - w.transform(b), axis=1)
    assert np.allclose(fast, slow, rtol=1e-6)
    assert np.allclose(np.cov(w.transform(x).T), np.eye(6), atol=1e-6)
    unit = w.apply(a)
    assert unit.dtype == np.float32 and np.allclose(np.linalg.norm(unit, axis=1), 1, atol=1e-6)


def test_the_null_space_is_dropped_and_eps_damps_weak_directions():
    x = _correlated(d=8, rank=3)                     # 8 values, 3 degrees of freedom
    w = whitening.fit(x)
    assert w.axes.shape == (8, 3) and np.allclose(w.axes.T @ w.axes, np.eye(3), atol=1e-9)
    damped = whitening.fit(x, eps=1e-2)
    assert np.all(damped.scales > w.scales) and damped.scales[-1] / w.scales[-1] > 5


def test_nan_rows_stay_nan_and_bad_inputs_are_named():
    w = whitening.fit(_correlated())
    d = _correlated(n=3)
    d[1] = np.nan
    out = w.apply(d)
    assert np.isnan(out[1]).all() and np.isfinite(out[[0, 2]]).all()
    with pytest.raises(sphere_jax.SphereJaxError, match=r"descriptors must be \[K, 6\]"):
        w.apply(np.zeros((2, 5)))
    with pytest.raises(sphere_jax.SphereJaxError, match="N > D"):
        whitening.fit(np.zeros((4, 6)))
    with pytest.raises(sphere_jax.SphereJaxError, match="finite"):
        whitening.fit(np.full((40, 6), np.nan))


def test_files_round_trip_keep_other_sources_and_name_a_bad_file(tmp_path):
    a, b = whitening.fit(_correlated(seed=1)), whitening.fit(_correlated(seed=2))
    whitening.save(tmp_path, {"default": a}, {"default": {"keypoints": 4000}})
    whitening.save(tmp_path, {"compass": b}, {"compass": {"keypoints": 4000}})
    back = whitening.load(tmp_path)
    assert set(back) == {"default", "compass"}
    assert np.allclose(back["compass"].axes, b.axes, atol=1e-6)
    assert set(whitening.read_statement(tmp_path)) == {"default", "compass"}
    with pytest.raises(sphere_jax.SphereJaxError, match="sources among"):
        whitening.save(tmp_path, {"flare": a}, {})
    (tmp_path / whitening.FILE).write_bytes(b"not an npz")
    with pytest.raises(sphere_jax.SphereJaxError, match="whitening.npz does not read"):
        whitening.load(tmp_path)
    # A copy (an install) with the statement but not the arrays never describes unwhitened.
    (tmp_path / whitening.FILE).unlink()
    with pytest.raises(sphere_jax.SphereJaxError,
                       match="whitening.json states the whitening of compass, default but "
                             "whitening.npz is missing"):
        whitening.load(tmp_path)


def _so3_maps(n, b, seed=0):
    """``[n, (2b)³]`` band-limited SO(3) maps, strongly anisotropic in their common pose."""
    rng = np.random.default_rng(seed)
    basis = rng.normal(size=(6, (2 * b) ** 3)) * np.logspace(0, -2, 6)[:, None]
    grid = rng.normal(size=(n, 6)) @ basis + 0.3 * basis[0]
    band = transforms.so3_ifft(transforms.so3_fft(grid.reshape((n,) + (2 * b,) * 3)))
    return np.asarray(band, np.float64).reshape(n, -1)


def _turned(maps, rotations, b):
    cubes = jnp.asarray(maps.reshape((-1,) + (2 * b,) * 3), jnp.float32)
    out = jax.vmap(transforms.rotate_so3)(cubes, jnp.asarray(rotations, jnp.float32))
    return np.asarray(out, np.float64).reshape(len(maps), -1)


def test_the_rotation_averaged_whitening_is_equivariant_and_whitens_turned_maps():
    """Fitted on maps in one pose, averaged over SO(3): turning every map by one rotation
    leaves whitened distances unchanged (the plain whitening's change), and maps turned to
    random poses come out with unit covariance on the kept directions."""
    b = 2
    maps = _so3_maps(3000, b)
    plain = whitening.fit(maps)
    averaged = whitening.rotation_averaged(plain, b)
    assert averaged.axes.shape[1] == sum((2 * l + 1) ** 2 for l in range(b))      # 10

    q = np.asarray(so3.random_rotation(jax.random.PRNGKey(1)))
    few = maps[:40]
    moved = _turned(few, np.repeat(q[None], len(few), 0), b)

    def distances(w, x):
        y = w.apply(x)
        return np.linalg.norm(y[:, None] - y[None], axis=-1)

    assert np.abs(distances(averaged, moved) - distances(averaged, few)).max() < 1e-5
    assert np.abs(distances(plain, moved) - distances(plain, few)).max() > 0.1

    # The slow reference: the same maps turned to random poses, whitened, have unit variance
    # in every kept direction (Monte Carlo over 3000 rotations: a few per cent).
    poses = np.asarray(so3.random_rotation(jax.random.PRNGKey(2), (len(maps),)))
    spread = _turned(maps, poses, b)
    cov = np.cov((averaged.transform(spread) @ averaged.axes).T)
    assert np.allclose(np.diag(cov), 1.0, atol=0.15), np.diag(cov).round(2)
    assert np.abs(cov - np.diag(np.diag(cov))).max() < 0.1
    with pytest.raises(sphere_jax.SphereJaxError, match="SO.3. maps at B = 3"):
        whitening.rotation_averaged(plain, 3)


@pytest.mark.slow
def test_a_fitted_whitening_is_what_describe_applies_and_the_card_states(tmp_path):
    config = sound.get_config("tiny")                # trained on embedded:1, like 'mid'
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    variables = reference.init(model, x * 0.3)
    training.checkpoints.save_bundle(str(tmp_path), config, {
        "params": variables["params"], "batch_stats": variables["batch_stats"]})
    path = tmp_path / "bundle"
    cloud = np.random.default_rng(1).uniform(-1, 1, (3000, 3)).astype(np.float32)
    kp = np.arange(20)
    raw = inference.cached_bundle(path).describe(cloud, kp, radius=0.5)     # none fitted yet
    used = whitening_fit.fit_bundle(path, scans=3, keypoints=250, command="whiten it",
                                    progress=False)
    assert used["default"] > 512 and set(used) == {"default"}        # SOUND: its own frames
    bundle = inference.cached_bundle(path)                 # the cache sees the new file
    w = bundle.whitenings["default"]
    assert np.allclose(bundle.describe(cloud, kp, radius=0.5), w.apply(raw), atol=1e-5)
    assert np.array_equal(bundle.describe(cloud, kp, radius=0.5, whiten=None), raw)
    with pytest.raises(sphere_jax.SphereJaxError, match="a whitening this sound bundle has "
                                                         r"\(default\)"):
        bundle.describe(cloud, kp, radius=0.5, whiten="compass")
    with pytest.raises(sphere_jax.SphereJaxError, match="whiten must be one of"):
        bundle.describe(cloud, kp, radius=0.5, whiten="flare")
    statement = whitening.read_statement(path)["default"]
    assert len(statement["scans"]) == 3 and all(s.startswith("embedded/rooms-v2-seed1/")
                                               for s in statement["scans"])
    card = open(model_card.render(path)).read()
    assert f"descriptor whitening `default` (the kind's own frames): {used['default']} " \
           "keypoints of 3 training scans" in card and "`whiten it`" in card


@pytest.mark.slow
def test_too_few_keypoints_to_fit_are_refused_and_the_bundle_is_left_alone(tmp_path):
    import shutil
    copy = tmp_path / "bundle"
    shutil.copytree(shipped.bundle_path("lead_pn"), copy)
    before = (copy / whitening.FILE).read_bytes()
    with pytest.raises(sphere_jax.SphereJaxError, match="scans must be enough to describe "
                                                         "more keypoints than the descriptor's "
                                                         r"512 values.*got 100 described"):
        whitening_fit.fit_bundle(copy, scans=1, keypoints=100, progress=False)
    assert (copy / whitening.FILE).read_bytes() == before
