import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.spherical import so3


def test_euler_matrix_round_trip_and_convention():
    rng = np.random.default_rng(0)
    a, b, g = rng.uniform(0, 2 * np.pi, 100), rng.uniform(0.01, np.pi - 0.01, 100), \
        rng.uniform(0, 2 * np.pi, 100)
    rot = so3.euler_to_matrix(a, b, g)
    np.testing.assert_allclose(rot, so3.euler_to_matrix_np(a, b, g), atol=1e-6)
    back = so3.euler_to_matrix(*so3.matrix_to_euler(rot))
    assert np.abs(back - rot).max() < 1e-5
    # R(α, β, 0) ẑ is the sphere point (β, α); Rz(α) turns x̂ towards ŷ (right-handed, active).
    np.testing.assert_allclose(np.asarray(rot)[:, :, 2], so3.sphere_points(b, a), atol=1e-6)
    np.testing.assert_allclose(so3.euler_to_matrix(np.pi / 2, 0.0, 0.0) @ jnp.array([1., 0, 0]),
                               [0, 1, 0], atol=1e-7)


def test_random_rotations_are_uniform_rotations():
    rot = np.asarray(so3.random_rotation(jax.random.PRNGKey(0), (20000,)), np.float64)
    np.testing.assert_allclose(rot @ rot.transpose(0, 2, 1), np.broadcast_to(np.eye(3), rot.shape),
                               atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-5)
    # Haar: E[R] = 0 and the angle has density (1 - cos θ)/π, so E[cos θ] = -1/2.
    assert np.abs(rot.mean(0)).max() < 0.02
    cos = (np.trace(rot, axis1=1, axis2=2) - 1) / 2
    assert abs(cos.mean() + 0.5) < 0.01


def test_geodesic_distance_known_angles_and_gradients():
    for theta in [0.3, np.pi / 2, 2.5]:
        a = so3.euler_to_matrix(0.4, 1.1, -0.3)
        b = a @ so3.euler_to_matrix(0.0, theta, 0.0)
        assert abs(float(so3.geodesic_distance(a, b)) - theta) < 2e-5
    for theta in [0.0, np.pi]:
        grad = jax.grad(lambda t: so3.geodesic_distance(
            jnp.eye(3), so3.euler_to_matrix(0.0, t, 0.0)))(jnp.float32(theta))
        assert np.isfinite(grad)


def test_quadrature_integrates_polynomials_in_cos_beta_exactly():
    b = 6
    beta = so3.grid_beta(b)
    w = so3.quadrature_weights(b)
    for k in range(2 * b):
        exact = (1 - (-1) ** (k + 1)) / (k + 1)                # ∫ cos^k β sin β dβ
        assert abs(np.sum(w * np.cos(beta) ** k) - exact) < 1e-12
    assert abs(so3.haar_weights(b).sum() * (2 * b) ** 2 - 1) < 1e-12


def test_bad_bandwidth():
    for bad in [0, -1, 2.0, True]:
        with pytest.raises(ValueError, match="bandwidth"):
            so3.grid_beta(bad)
