import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.spherical import correlation, layers, so3, transforms
from tests import reference
from tests.reference import rel_err


@pytest.mark.parametrize("b_in, b_out", [(8, 8), (16, 16), (16, 12)])
@pytest.mark.parametrize("on_so3", [False, True])
def test_layer_equivariance(on_so3, b_in, b_out):
    rng = np.random.default_rng(b_in + b_out)
    cls = layers.SO3Conv if on_so3 else layers.S2Conv
    if on_so3:
        x = transforms.so3_ifft(reference.random_so3_coeffs(rng, (2, 3), b_in), b_in)
        rotate_in = transforms.rotate_so3
    else:
        x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (2, 3), b_in), b_in)
        rotate_in = transforms.rotate_s2
    model = cls(features=4, b_in=b_in, b_out=b_out)
    params = reference.init(model, x)
    apply = jax.jit(model.apply)
    for seed in range(2):
        rot = so3.random_rotation(jax.random.PRNGKey(10 + seed))
        lhs = apply(params, rotate_in(x, rot))
        rhs = transforms.rotate_so3(apply(params, x), rot)
        assert rel_err(lhs, rhs) < 1e-4


def test_activations_keep_unit_order_through_five_layers():
    """LEAD-shaped stack (S2Conv + 4 SO3Conv, ReLU between) at reduced bandwidths."""
    rng = np.random.default_rng(0)
    bands = (10, 8, 6, 5, 4, 3)
    x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (8, 4), 6), bands[0])
    x = x / jnp.std(x)
    h = x
    for i in range(5):
        cls = layers.S2Conv if i == 0 else layers.SO3Conv
        model = cls(features=40, b_in=bands[i], b_out=bands[i + 1])
        h = reference.apply(model, reference.init(model, h, seed=i), h)
        rms = float(jnp.sqrt(jnp.mean(h ** 2)))
        assert 0.3 < rms < 3.0, f"layer {i}: rms {rms}"
        h = jax.nn.relu(h)


def test_batch_norm_and_haar_pool():
    """Training-mode output has Haar mean 0 and Haar variance 1 per channel; the running
    statistics take one momentum step towards the batch's."""
    x = 3.0 + 2.0 * jax.random.normal(jax.random.PRNGKey(0), (4, 5, 6, 6, 6))
    bn = layers.GridBatchNorm()
    variables = bn.init(jax.random.PRNGKey(1), x, train=True)
    y, updates = bn.apply(variables, x, train=True, mutable=["batch_stats"])
    mean, mean_sq = (m.mean(0) for m in transforms.so3_grid_moments(y))
    assert float(jnp.abs(mean).max()) < 1e-4
    assert float(jnp.abs(mean_sq - 1).max()) < 1e-3
    x_mean = transforms.so3_grid_moments(x)[0].mean(0)
    stats = updates["batch_stats"]["BatchNorm_0"]
    assert rel_err(stats["mean"], 0.1 * x_mean) < 1e-5
    assert layers.haar_pool(x).shape == (4, 5)


def test_haar_moments_of_spectrum_and_grid_agree_and_ignore_rotation():
    """Degree-0 coefficient and Parseval sum against the SOFT quadrature on the grid, before
    and after rotating the band-limited signals; s2cnn's plain grid mean changes instead."""
    rng = np.random.default_rng(7)
    b = 6
    x = transforms.so3_ifft(reference.random_so3_coeffs(rng, (3, 4), b), b)
    spectral = lambda x: transforms.so3_moments(
        transforms.so3_analysis(x.reshape((-1,) + x.shape[2:]), b))
    m0, s0 = spectral(x)
    g0, q0 = transforms.so3_grid_moments(x)
    assert rel_err(m0, g0.reshape(-1)) < 1e-5 and rel_err(s0, q0.reshape(-1)) < 1e-5
    rot = so3.random_rotation(jax.random.PRNGKey(3))
    xr = transforms.rotate_so3(x, rot)
    g1, q1 = transforms.so3_grid_moments(xr)
    assert rel_err(g1, g0) < 1e-5 and rel_err(q1, q0) < 1e-5
    plain = lambda x: x.mean((-3, -2, -1))
    assert rel_err(plain(xr), plain(x)) > 1e-2


def test_batch_norm_statistics_unchanged_by_rotation():
    rng = np.random.default_rng(8)
    b = 6
    x = transforms.so3_ifft(reference.random_so3_coeffs(rng, (3, 4), b), b)
    bn = layers.GridBatchNorm()
    v = bn.init(jax.random.PRNGKey(0), x, train=True)
    stats = lambda x: bn.apply(v, x, train=True, mutable=["batch_stats"])[1]["batch_stats"]
    rot = so3.random_rotation(jax.random.PRNGKey(4))
    a, r = stats(x)["BatchNorm_0"], stats(transforms.rotate_so3(x, rot))["BatchNorm_0"]
    assert rel_err(r["mean"], a["mean"]) < 1e-5 and rel_err(r["var"], a["var"]) < 1e-5


def test_gradients_are_finite():
    x = jax.random.normal(jax.random.PRNGKey(0), (2, 3, 8, 8, 8))
    model = layers.SO3Conv(features=2, b_in=4, b_out=3)
    params = reference.init(model, x, seed=1)
    grads = jax.jit(jax.grad(lambda p: jnp.sum(model.apply(p, x) ** 2)))(params)
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in jax.tree_util.tree_leaves(grads))


def test_bad_inputs():
    x = jnp.zeros((2, 3, 8, 8, 8))
    with pytest.raises(ValueError, match="expects b_in=6"):
        layers.SO3Conv(features=2, b_in=6, b_out=4).init(jax.random.PRNGKey(0), x)
    with pytest.raises(ValueError, match="b_out=5 > b_in=4"):
        layers.SO3Conv(features=2, b_in=4, b_out=5).init(jax.random.PRNGKey(0), x)
    s2_grid = correlation.make_grid("near_identity", on_so3=False)
    with pytest.raises(ValueError, match="needs an SO\\(3\\) grid"):
        layers.SO3Conv(features=2, b_in=4, b_out=4, grid=s2_grid).init(jax.random.PRNGKey(0), x)
    # An SO(3) grid is not a batch of S2 grids with 2B channels (it used to be read as one).
    with pytest.raises(ValueError, match=r"the input of S2Conv must be an S2 grid \[N, C, 2B, "
                                         r"2B\]; got shape \(2, 3, 8, 8, 8\)"):
        layers.S2Conv(features=2, b_in=4, b_out=4).init(jax.random.PRNGKey(0), x)
    with pytest.raises(ValueError, match=r"SO\(3\) grid \[N, C, 2B, 2B, 2B\]"):
        layers.SO3Conv(features=2, b_in=4, b_out=4).init(jax.random.PRNGKey(0), x[:, 0])
    with pytest.raises(ValueError, match="SO3Conv.features must be a positive integer; got 0"):
        layers.SO3Conv(features=0, b_in=4, b_out=4).init(jax.random.PRNGKey(0), x)


def test_parameters_of_another_channel_count_are_named():
    conv = layers.SO3Conv(features=4, b_in=4, b_out=4)
    v = conv.init(jax.random.PRNGKey(0), jnp.ones((1, 3, 8, 8, 8)))
    with pytest.raises(ValueError, match=r"input of SO3Conv must be 3 channels \(its "
                                         r"parameters map 3 to 4\); got 6 channels"):
        conv.apply(v, jnp.ones((1, 6, 8, 8, 8)))
