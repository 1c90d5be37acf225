"""The learned-x̂ frame: a proper rotation that turns exactly with its patch (its weights see
only invariant features), its ẑ FLARE's normal of the support."""
import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax.models import flare, lrf_net


def _patches(seed=0, n=6, p=300):
    x = jax.random.normal(jax.random.PRNGKey(seed), (n, p, 3)) * 0.4
    x = x.at[:, :, 2].multiply(0.25)                  # a bumpy surface, not a ball
    return x.at[:, 0].set(0.0)                        # the keypoint itself


def _rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return jnp.asarray(q * np.linalg.det(q), jnp.float32)


def test_the_frame_turns_with_the_patch_and_is_a_rotation():
    model = lrf_net.LrfNet(point=(8, 8), score=(8, 8))
    patches = _patches()
    variables = model.init(jax.random.PRNGKey(1), patches)
    out = model.apply(variables, patches)
    r = _rotation(3)
    turned = model.apply(variables, patches @ r.T)
    assert float(jnp.abs(turned.rotations - r @ out.rotations).max()) < 1e-5
    eye = jnp.einsum("nji,njk->nik", out.rotations, out.rotations)
    assert float(jnp.abs(eye - jnp.eye(3)).max()) < 1e-5
    assert np.allclose(np.linalg.det(np.asarray(out.rotations)), 1.0, atol=1e-5)
    assert np.allclose(out.weights.sum(-1), 1.0, atol=1e-5)
    assert float(out.weights[:, 0].max()) == 0.0              # the keypoint has no say
    z = jax.vmap(flare.support_normal, (0, None))(patches, 0.5)
    assert float(jnp.abs(out.rotations[..., 2] - z).max()) < 1e-6


def test_the_support_normal_is_the_fitted_plane_s_turned_away_from_the_mass():
    """On a cup (z = 0.3 (x² + y²), its mass above the keypoint's tangent plane) the normal is
    -ẑ, turned with the cup; the inner points alone decide it."""
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.7, 0.7, (400, 2))
    cup = np.c_[xy, 0.3 * (xy ** 2).sum(1)].astype(np.float32)
    assert np.allclose(flare.support_normal(cup, 0.5), [0, 0, -1], atol=0.02)
    r = _rotation(5)
    assert np.allclose(flare.support_normal(cup @ np.asarray(r).T, 0.5), r @ jnp.array(
        [0.0, 0.0, -1.0]), atol=0.02)
