import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.models import losses
from sphere_jax.spherical import so3


def test_geodesic_loss_known_pairs():
    a = so3.random_rotation(jax.random.PRNGKey(0), (4,))
    angles = jnp.array([0.1, 1.0, 2.0, 3.0])
    b = a @ so3.euler_to_matrix(0.0 * angles, angles, 0.0 * angles)
    assert abs(float(losses.geodesic_loss(a, b)) - float(angles.mean())) < 1e-4
    # Identical rotations: only the clip inside ±1 separates it from 0.
    assert float(losses.geodesic_loss(a, a)) < 1e-3


@pytest.mark.parametrize("theta", [0.0, np.pi])
def test_geodesic_loss_gradient_finite_at_0_and_pi(theta):
    target = so3.euler_to_matrix(0.3, theta, -0.3)

    def loss(angles):
        return losses.geodesic_loss(so3.euler_to_matrix(*angles), target)

    g = jax.grad(loss)(jnp.array([0.3, 0.0, -0.3]))
    assert bool(jnp.all(jnp.isfinite(g)))


def test_chamfer_against_brute_force():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 50, 3)), rng.normal(size=(2, 70, 3))
    d2 = ((a[:, :, None] - b[:, None]) ** 2).sum(-1)
    expect = d2.min(2).mean(1) + d2.min(1).mean(1)
    got = losses.chamfer_distance(jnp.asarray(a, jnp.float32), jnp.asarray(b, jnp.float32))
    np.testing.assert_allclose(got, expect, rtol=1e-4)
    assert float(losses.chamfer_distance(jnp.asarray(a[0]), jnp.asarray(a[0]))) < 1e-5
    g = jax.grad(lambda x: losses.chamfer_distance(x, jnp.asarray(b[0])))(jnp.asarray(a[0]))
    assert bool(jnp.all(jnp.isfinite(g)))


def test_chamfer_gradient_equals_that_of_the_dense_minimum():
    """Batches larger than one search chunk (NN_CHUNK), against autodiff of the dense
    formula: the gradient goes to each point's nearest neighbour either way."""
    rng = np.random.default_rng(1)
    a = jnp.asarray(rng.normal(size=(3, 4, 40, 3)), jnp.float32)
    b = jnp.asarray(rng.normal(size=(3, 4, 60, 3)), jnp.float32)

    def dense(a, b):
        d2 = jnp.sum((a[..., :, None, :] - b[..., None, :, :]) ** 2, -1)
        return jnp.sum(d2.min(-1).mean(-1) + d2.min(-2).mean(-1))

    chunked = lambda a, b: jnp.sum(losses.chamfer_distance(a, b))
    assert losses.chamfer_distance(a, b).shape == (3, 4) and 3 * 4 > losses.NN_CHUNK
    np.testing.assert_allclose(chunked(a, b), dense(a, b), rtol=1e-5)
    for got, want in zip(jax.grad(chunked, (0, 1))(a, b), jax.grad(dense, (0, 1))(a, b)):
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-7)


def test_bad_inputs():
    with pytest.raises(ValueError, match="pred_x33 and target_x33"):
        losses.geodesic_loss(jnp.eye(3)[None], jnp.eye(3))
    with pytest.raises(ValueError, match="non-empty"):
        losses.chamfer_distance(jnp.zeros((0, 3)), jnp.zeros((4, 3)))
    with pytest.raises(ValueError, match="a_Nx3 and b_Mx3"):
        losses.chamfer_distance(jnp.zeros((5, 2)), jnp.zeros((4, 3)))


@pytest.mark.parametrize("axis", [0, 1, -1])
def test_first_argmin_is_argmin_with_ties(axis):
    """Small integers make many ties: the first index of the minimum, as jnp.argmin."""
    x = jnp.asarray(np.random.default_rng(3).integers(0, 4, size=(7, 9, 5)), jnp.float32)
    np.testing.assert_array_equal(losses.first_argmin(x, axis), jnp.argmin(x, axis))
