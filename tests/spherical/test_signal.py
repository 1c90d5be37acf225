import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.spherical import signal, so3, transforms


def ball(rng, n, radius=1.0):
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return (p * radius * rng.uniform(size=(n, 1)) ** (1 / 3)).astype(np.float32)


def blob_patch(rng, n=1225):
    """An anisotropic, surface-like patch: a bumpy sheet with a ridge, inside the unit ball."""
    uv = rng.uniform(-0.7, 0.7, size=(n, 2))
    z = 0.25 * np.sin(3 * uv[:, 0]) + 0.15 * uv[:, 1] ** 2 + 0.3 * np.exp(-20 * uv[:, 0] ** 2)
    return np.concatenate([uv, z[:, None]], 1).astype(np.float32)


def test_uniform_ball_reads_one_whatever_n():
    rng = np.random.default_rng(0)
    for n in [50_000, 200_000]:
        s = np.asarray(signal.patch_signal(ball(rng, n), 1.0, 6, 4))
        assert abs(s.mean() - 1) < 0.02
        assert np.percentile(np.abs(s - 1), 90) < 3 / np.sqrt(n / s.size)


@pytest.mark.parametrize("k", [1, 5])
def test_z_rotation_by_grid_step_shifts_exactly(k):
    b = 8
    patch = blob_patch(np.random.default_rng(1))
    rot = so3.euler_to_matrix_np(2 * np.pi * k / (2 * b), 0.0, 0.0).astype(np.float32)
    s = np.asarray(signal.patch_signal(patch, 1.0, b))
    s_rot = np.asarray(signal.patch_signal(patch @ rot.T, 1.0, b))
    assert np.abs(np.roll(s, k, axis=-1) - s_rot).max() < 1e-4 * np.abs(s).max()


def test_arbitrary_rotation_discretisation_error(capsys):
    """signal(R·P) vs L_R signal(P): the grid is not rotation invariant, so this is bounded, not 0.

    Both sides are low-pass filtered to degree < B/2 before comparing (the grid
    resolves the low degrees only; the comparison is what a spherical CNN sees).
    """
    b = 12
    rng = np.random.default_rng(2)
    patch = blob_patch(rng, 20_000)
    errs = []
    for seed in range(3):
        rot = so3.random_rotation(jax.random.PRNGKey(seed))
        s_rot = signal.patch_signal(patch @ np.asarray(rot).T, 1.0, b)
        lhs = transforms.s2_ifft(transforms.s2_fft(s_rot, b // 2), b)
        rhs = transforms.s2_ifft(transforms.rotate_s2_coeffs(
            transforms.s2_fft(signal.patch_signal(patch, 1.0, b), b // 2), rot), b)
        errs.append(float(jnp.linalg.norm(lhs - rhs) / jnp.linalg.norm(rhs)))
    with capsys.disabled():
        print(f"\n  patch signal, B={b}, low-pass < {b // 2}: relative error of "
              f"signal(R P) vs L_R signal(P) = {np.round(errs, 3)}")
    assert max(errs) < 0.15


def test_sample_patch_excludes_keypoint_and_stays_in_radius():
    rng = np.random.default_rng(3)
    cloud = rng.uniform(-1, 1, size=(2000, 3)).astype(np.float32)
    centre = cloud[7]
    local, count = signal.sample_patch(jax.random.PRNGKey(0), cloud, centre, 0.5, 1225)
    dist = np.linalg.norm(cloud - centre, axis=1)
    assert int(count) == int(np.sum((dist <= 0.5) & (dist > 0)))
    r = np.linalg.norm(np.asarray(local), axis=1)
    assert local.shape == (1225, 3) and r.max() <= 0.5 + 1e-6 and r.min() > 0
    keys = jax.random.split(jax.random.PRNGKey(1), 4)
    batch, counts = jax.vmap(signal.sample_patch, (0, None, 0, None, None))(
        keys, cloud, cloud[:4], 0.5, 100)
    assert batch.shape == (4, 100, 3) and counts.shape == (4,)


def test_batched_signals_match_single_and_are_differentiable():
    rng = np.random.default_rng(4)
    # One step of PATCHES_PER_STEP patches and a remainder.
    n = signal.PATCHES_PER_STEP + 3
    patches = np.stack([blob_patch(rng, 300) for _ in range(n)])
    batch = signal.patch_signals(patches, 1.0, 6)
    single = np.stack([signal.patch_signal(p, 1.0, 6) for p in patches])
    np.testing.assert_allclose(batch, single, rtol=1e-5, atol=1e-5)
    g = jax.grad(lambda p: jnp.sum(signal.patch_signal(p, 1.0, 6) ** 2))(patches[0])
    assert np.all(np.isfinite(g))


def test_bad_inputs():
    good = np.ones((10, 3), np.float32)
    with pytest.raises(ValueError, match=r"patch_Nx3 must have shape \[N, 3\]"):
        signal.patch_signal(np.ones((10, 2)), 1.0, 4)
    with pytest.raises(ValueError, match="is empty"):
        signal.patch_signal(np.zeros((0, 3)), 1.0, 4)
    bad = good.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="1 point\\(s\\) with NaN"):
        signal.patch_signal(bad, 1.0, 4)
    with pytest.raises(ValueError, match=r"patches_PxNx3 must have shape \[P, N, 3\]"):
        signal.patch_signals(good, 1.0, 4)
    with pytest.raises(ValueError, match="b must be a positive integer"):
        signal.patch_signal(good, 1.0, 0)


def test_bad_radius():
    with pytest.raises(ValueError, match="radius must be one positive number"):
        signal.patch_signal(np.ones((10, 3), np.float32), 0.0, 4)
    with pytest.raises(ValueError, match="radius must be one positive number"):
        signal.patch_signals(np.ones((1, 10, 3), np.float32), float("nan"), 4)
    with pytest.raises(ValueError, match=r"one positive number, got an array of shape \(2,\)"):
        signal.patch_signals(np.ones((2, 10, 3), np.float32), np.array([0.3, 0.3]), 4)
