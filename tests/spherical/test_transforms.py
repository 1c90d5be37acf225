import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.spherical import so3, transforms
from tests import reference
from tests.reference import rel_err


@pytest.mark.parametrize("b, lmax", [(8, 8), (16, 16), (12, 7)])
def test_round_trip_on_band_limited_coefficients(b, lmax):
    rng = np.random.default_rng(b)
    c2 = reference.random_s2_coeffs(rng, (3, 2), lmax)
    assert rel_err(transforms.s2_fft(transforms.s2_ifft(c2, b), lmax), c2) < 1e-5
    c3 = reference.random_so3_coeffs(rng, (3,), lmax)
    assert rel_err(transforms.so3_fft(transforms.so3_ifft(c3, b), lmax), c3) < 1e-5


@pytest.mark.parametrize("b", [4, 5, 6, 7, 8])
def test_against_direct_sums(b):
    rng = np.random.default_rng(b)
    lmax = b
    d_table = reference.wigner_d_explicit_table(lmax, so3.grid_beta(b))
    c2 = reference.random_s2_coeffs(rng, (2,), lmax)
    x2 = reference.s2_synth_grid(c2, b, d_table)
    assert rel_err(transforms.s2_ifft(c2, b), x2) < 1e-5
    assert rel_err(transforms.s2_fft(x2.astype(np.float32)), c2) < 1e-5
    c3 = reference.random_so3_coeffs(rng, (2,), lmax)
    x3 = reference.so3_synth_grid(c3, b, d_table)
    assert rel_err(transforms.so3_ifft(c3, b), x3) < 1e-5
    assert rel_err(transforms.so3_fft(x3.astype(np.float32)), c3) < 1e-5


def test_band_limit_change_is_truncation():
    rng = np.random.default_rng(0)
    c = reference.random_so3_coeffs(rng, (2,), 10)
    x = transforms.so3_ifft(c, 10)
    assert rel_err(transforms.so3_fft(x, 6), c[..., :6, 9 - 5:9 + 6, :6]) < 1e-5
    # Upsampling the grid keeps the function: evaluate on the finer grid directly.
    lo = reference.random_s2_coeffs(rng, (), 5)
    fine = transforms.s2_ifft(lo, 9)
    beta, alpha = so3.s2_grid(9)
    assert rel_err(fine, reference.s2_eval(lo, beta.ravel(), alpha.ravel()).reshape(18, 18)) < 1e-5


def test_spectral_rotation_matches_direct_evaluation():
    rng = np.random.default_rng(3)
    rot = np.asarray(so3.random_rotation(jax.random.PRNGKey(3)), np.float64)
    b = 6
    c2 = reference.random_s2_coeffs(rng, (), b)
    beta, alpha = so3.s2_grid(b)
    pts = so3.sphere_points(beta.ravel(), alpha.ravel())
    src = np.asarray(pts, np.float64) @ rot                           # R⁻¹ x, row vectors
    expect = reference.s2_eval(c2, np.arccos(np.clip(src[:, 2], -1, 1)),
                               np.arctan2(src[:, 1], src[:, 0])).reshape(2 * b, 2 * b)
    got = transforms.rotate_s2(transforms.s2_ifft(c2, b), rot.astype(np.float32))
    assert rel_err(got, expect) < 1e-5

    c3 = reference.random_so3_coeffs(rng, (), b)
    grid = so3.so3_grid_matrices(b).reshape(-1, 3, 3)
    expect = reference.so3_eval_rot(c3, np.einsum("ji,gjk->gik", rot, grid)).reshape((2 * b,) * 3)
    got = transforms.rotate_so3(transforms.so3_ifft(c3, b), rot.astype(np.float32))
    assert rel_err(got, expect) < 1e-5


def test_haar_mean_is_exact_and_rotation_invariant():
    rng = np.random.default_rng(5)
    c = reference.random_so3_coeffs(rng, (3,), 6)
    x = transforms.so3_ifft(c, 6)
    # The mean of Σ f̂ conj D is f̂^0_{00} (D^0 = 1).
    np.testing.assert_allclose(transforms.so3_haar_mean(x), c[:, 0, 5, 0].real, atol=1e-5)
    xr = transforms.rotate_so3(x, so3.random_rotation(jax.random.PRNGKey(1)))
    np.testing.assert_allclose(transforms.so3_haar_mean(xr), transforms.so3_haar_mean(x),
                               atol=1e-5)


def test_transforms_are_differentiable_and_vmappable():
    x = jax.random.normal(jax.random.PRNGKey(0), (4, 2, 8, 8, 8))
    g = jax.grad(lambda v: jax.numpy.sum(transforms.so3_ifft(transforms.so3_fft(v, 3)) ** 2))(x)
    assert np.all(np.isfinite(g))
    batched = jax.vmap(transforms.s2_fft)(x[:, :, 0])
    np.testing.assert_allclose(batched, transforms.s2_fft(x[:, :, 0]), atol=1e-6)


def test_bad_inputs():
    with pytest.raises(ValueError, match="grid axes"):
        transforms.s2_fft(np.zeros((3, 8, 6), np.float32))
    with pytest.raises(ValueError, match="grid axes"):
        transforms.so3_fft(np.zeros((7, 7, 7), np.float32))
    with pytest.raises(ValueError, match="lmax=9 exceeds"):
        transforms.s2_fft(np.zeros((16, 16), np.float32), 9)
    with pytest.raises(ValueError, match="coeffs must have shape"):
        transforms.so3_ifft(np.zeros((4, 6, 4), np.complex64))
    with pytest.raises(ValueError, match="lmax=5 exceeds"):
        transforms.s2_ifft(np.zeros((5, 5), np.complex64), 3)
    # The internal real layouts, which the layers call directly: our message, not einsum's.
    with pytest.raises(ValueError, match=r"x_XxJxA must have shape \[X, 2B, 2B\]; got \(8, 8\)"):
        transforms.s2_analysis(jnp.zeros((8, 8)), 4)
    with pytest.raises(ValueError, match="lmax=9 exceeds"):
        transforms.so3_analysis(jnp.zeros((1, 8, 8, 8)), 9)
    with pytest.raises(ValueError, match=r"h_MxLx2xX must have shape \[L, L, 2, X\]"):
        transforms.s2_synthesis(jnp.zeros((4, 3, 2, 1)), 4)
    with pytest.raises(ValueError, match=r"h_MxNxLx2xX must have shape \[2L-1, L, L, 2, X\]"):
        transforms.so3_synthesis(jnp.zeros((4, 4, 4, 2, 1)), 4)
    with pytest.raises(ValueError, match=r"must be rotations \[\.\.\., 3, 3\]"):
        so3.geodesic_distance(jnp.eye(3), jnp.ones((4, 3)))


@pytest.mark.parametrize("rot, message", [
    (np.eye(2), r"rot_33 must be a rotation matrix \[3, 3\]; got shape \(2, 2\)"),
    (2 * np.eye(3), r"must be a rotation \(RᵀR = I and det R = \+1 within 0.001\); got "
                    r"\|RᵀR − I\| = 3"),
    (np.diag([1.0, 1.0, -1.0]), r"det R = -1"),
])
def test_a_rotation_that_is_not_one_is_refused_eagerly(rot, message):
    x = jnp.ones((8, 8))
    with pytest.raises(ValueError, match=message):
        transforms.rotate_s2(x, rot)
    r = so3.random_rotation(jax.random.PRNGKey(0))          # and under jit it still runs
    np.testing.assert_allclose(jax.jit(transforms.rotate_s2)(x, r), transforms.rotate_s2(x, r),
                               atol=1e-5)
