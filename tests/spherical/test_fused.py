"""The fused inference path against the layer-by-layer one it replaces."""
import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.spherical import correlation, fused, layers, transforms
from sphere_jax.models.spherical import SphericalStack
from tests import reference
from tests.reference import rel_err


def _spectrum(rng, n, c, b, lmax):
    x = transforms.so3_ifft(reference.random_so3_coeffs(rng, (n, c), lmax), b)
    return fused.analyse(x, lmax, on_so3=True)


@pytest.mark.parametrize("block_floats, b, l_in", [
    (1, 6, 6), (2 * 3 * 12 ** 3, 6, 6), (10 ** 9, 6, 6), (2 * 3 * 10 ** 3, 5, 3)])
def test_pointwise_equals_synthesis_relu_analysis(block_floats, b, l_in):
    """Blocks of one channel, of 2 patches and of all 6; the reference runs :mod:`transforms`
    on whole grids. Odd B and L_in < B exercise the radix-2 α step's folding."""
    rng = np.random.default_rng(0)
    n, c, l_out = 6, 3, 4
    h = _spectrum(rng, n, c, b, l_in)
    scale, shift = rng.normal(size=c), rng.normal(size=c)
    got = fused.pointwise(h, scale, shift, l_out, block_floats=block_floats)
    grid = fused.synthesise(h) * scale[:, None, None, None] + shift[:, None, None, None]
    want = transforms.so3_analysis(jax.nn.relu(grid).reshape((n * c,) + grid.shape[2:]), l_out)
    assert got.coeffs.shape == want.shape
    assert rel_err(got.coeffs, want) < 1e-5
    assert rel_err(fused.pointwise(h, scale, shift, l_out, relu=False).coeffs,
                   transforms.so3_analysis(grid.reshape(want.shape[-1:] + grid.shape[2:]),
                                           l_out)) < 1e-5


def test_s2_product_blocks_equal_whole_product():
    rng = np.random.default_rng(1)
    x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (4, 2), 5), 5)
    grid = correlation.make_grid("near_identity", on_so3=False)
    w = jnp.asarray(rng.normal(size=grid.shape + (2, 3)), jnp.float32)
    prod = fused.correlate(fused.analyse(x, 4, on_so3=False), w, grid, 4)
    want = correlation.s2_correlate(x, w, grid, 4)
    assert rel_err(fused.synthesise(prod), want) < 1e-5
    whole = prod.coeffs                                               # 4 patches x 3 channels
    assert rel_err(prod.block(6, 6), whole[..., 6:]) < 1e-6             # patches 2, 3
    assert rel_err(prod.block(7, 1), whole[..., 7:8]) < 1e-6            # patch 2, channel 1


def test_s2_product_moments_from_its_factors_equal_those_of_the_product():
    """Batch norm's statistics of an S2 layer's output, taken from the factors without
    forming the product: the same values and gradients as the dense product's Parseval sum,
    which the SOFT quadrature of its grid confirms."""
    rng = np.random.default_rng(2)
    n, c, d, lmax = 3, 4, 5, 6
    x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (n, c), 7), 7)
    grid = correlation.make_grid("near_identity", on_so3=False)
    w = jnp.asarray(rng.normal(size=grid.shape + (c, d)), jnp.float32)
    f = fused.analyse(x, lmax, on_so3=False)
    prod = fused.correlate(f, w, grid, lmax)
    dense = lambda p: tuple(m.reshape(n, d) for m in transforms.so3_moments(p.coeffs))
    got, want = fused.moments(prod), dense(prod)
    on_grid = transforms.so3_grid_moments(fused.synthesise(prod))
    for g, e, q in zip(got, want, on_grid):
        assert g.shape == (n, d)
        assert rel_err(g, e) < 1e-5 and rel_err(g, q) < 1e-4
    weights = jnp.asarray(rng.normal(size=(n, d)), jnp.float32)
    loss = lambda moments: lambda w: sum(jnp.sum(m * weights) for m in moments(
        fused.correlate(f, w, grid, lmax)))
    assert rel_err(jax.grad(loss(fused.moments))(w), jax.grad(loss(dense))(w)) < 1e-5


@pytest.mark.parametrize("s2_first, final_relu", [(True, False), (True, True), (False, False)])
def test_stack_fused_equals_layer_by_layer(s2_first, final_relu):
    rng = np.random.default_rng(2)
    bands, feats = (8, 6, 5, 4), (5, 4, 2)
    if s2_first:
        x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (3, 2), 8), 8)
    else:
        x = jax.nn.relu(transforms.so3_ifft(reference.random_so3_coeffs(rng, (3, 2), 8), 8))
    stack = SphericalStack(feats, bands, s2_first=s2_first, final_relu=final_relu)
    variables = reference.init(stack, x, train=False)
    # Batch statistics away from (0, 1), so that the affine step is exercised.
    variables = reference.shifted_batch_stats(variables, rng)
    want = reference.apply(stack.clone(fused=False), variables, x, train=False)
    got = jax.jit(lambda v, x: stack.apply(v, x, train=False))(variables, x)
    assert got.shape == want.shape == (3, 2, 8, 8, 8)
    assert rel_err(got, want) < 1e-5
    # Same parameter tree either way: bundles trained before fusion load unchanged.
    plain = jax.eval_shape(lambda: stack.clone(fused=False).init(jax.random.PRNGKey(0), x,
                                                                 train=False))
    assert jax.tree_util.tree_structure(plain) == jax.tree_util.tree_structure(variables)


def test_batch_norm_of_a_spectrum_is_its_affine_map():
    rng = np.random.default_rng(3)
    x = jnp.asarray(rng.normal(size=(2, 3, 4, 4, 4)), jnp.float32)
    norm = layers.GridBatchNorm()
    v = norm.init(jax.random.PRNGKey(0), x, train=False)
    v = {"params": v["params"], "batch_stats": {"BatchNorm_0": {
        "mean": jnp.array([0.1, -0.2, 0.3]), "var": jnp.array([0.5, 2.0, 1.5])}}}
    scale, shift = norm.apply(v, fused.analyse(x, 2, on_so3=True), train=False)
    want = norm.apply(v, x, train=False)
    assert rel_err(x * scale[:, None, None, None] + shift[:, None, None, None], want) < 1e-6


def test_errors_name_the_mismatch():
    rng = np.random.default_rng(4)
    h = _spectrum(rng, 2, 3, 6, 4)
    conv = layers.SO3Conv(features=2, b_in=8, b_out=4)
    with pytest.raises(ValueError, match="b_in=8"):
        conv.init(jax.random.PRNGKey(0), h)
    grid = correlation.make_grid("near_identity", on_so3=True)
    with pytest.raises(ValueError, match="lmax=4"):
        fused.correlate(h, jnp.zeros(grid.shape + (3, 2)), grid, 3)
    with pytest.raises(ValueError, match="lmax"):
        fused.pointwise(h, np.ones(3), np.zeros(3), 7)


def test_blocks_divide_the_signals():
    assert fused._signals_per_block(12, 40, 16, 40 * 32 ** 3) == 40        # one patch
    assert fused._signals_per_block(12, 40, 8, 40 * 32 ** 3) == 6 * 40     # 8 fit, 6 divides 12
    assert fused._signals_per_block(7, 40, 8, 40 * 32 ** 3) == 7 * 40
    assert fused._signals_per_block(8, 40, 24, 40 * 32 ** 3) == 10         # channels of a patch
    assert fused._signals_per_block(5, 40, 24, 1) == 1


@pytest.mark.parametrize("on_so3", [True, False])
def test_truncate_equals_analysis_to_fewer_degrees(on_so3):
    rng = np.random.default_rng(5)
    if on_so3:
        x = transforms.so3_ifft(reference.random_so3_coeffs(rng, (2, 3), 6), 8)
    else:
        x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (2, 3), 6), 8)
    x = jax.nn.relu(x)                               # not band-limited: every degree matters
    got = fused.truncate(fused.analyse(x, 8, on_so3), 5)
    want = fused.analyse(x, 5, on_so3)
    assert got.coeffs.shape == want.coeffs.shape and got.bandwidth == want.bandwidth == 8
    assert rel_err(got.coeffs, want.coeffs) < 1e-5
    with pytest.raises(ValueError, match="lmax must be in"):
        fused.truncate(want, 6)


def test_spectrum_input_needs_the_fused_path():
    rng = np.random.default_rng(6)
    stack = SphericalStack((2,), (8, 6), s2_first=False, fused=False)
    h = fused.analyse(jax.nn.relu(transforms.so3_ifft(
        reference.random_so3_coeffs(rng, (1, 2), 6), 8)), 6, True)
    with pytest.raises(ValueError, match="needs the fused path"):
        stack.init(jax.random.PRNGKey(0), h, train=False)


@pytest.mark.parametrize("block_floats", [1, 2 * 3 * 12 ** 3, 10 ** 9])
def test_pointwise_gradients_equal_autodiff_of_whole_grids(block_floats):
    """The blocked backward pass (recomputed block grids) against JAX's gradient of synthesis
    -> affine -> ReLU -> analysis on whole grids, for a spectrum and for an S2 product (whose
    kernel, the layer's weights, gets the gradient)."""
    rng = np.random.default_rng(6)
    n, c, b, l_out = 4, 3, 6, 4
    h = _spectrum(rng, n, c, b, b)
    scale, shift = jnp.asarray(rng.normal(size=c)), jnp.asarray(rng.normal(size=c))
    probe = jnp.asarray(rng.normal(size=(2 * l_out - 1, l_out, l_out, 2, n * c)), jnp.float32)

    def whole(coeffs, scale, shift):
        grid = fused.synthesise(h._replace(coeffs=coeffs)) * scale[:, None, None, None] \
            + shift[:, None, None, None]
        flat = jax.nn.relu(grid).reshape((n * c,) + grid.shape[2:])
        return jnp.sum(transforms.so3_analysis(flat, l_out) * probe)

    def blocked(coeffs, scale, shift):
        out = fused.pointwise(h._replace(coeffs=coeffs), scale, shift, l_out,
                              block_floats=block_floats)
        return jnp.sum(out.coeffs * probe)

    want = jax.grad(whole, (0, 1, 2))(h.coeffs, scale, shift)
    got = jax.jit(jax.grad(blocked, (0, 1, 2)))(h.coeffs, scale, shift)
    for g, w in zip(got, want):
        assert rel_err(g, w) < 1e-5

    x = transforms.s2_ifft(reference.random_s2_coeffs(rng, (n, 2), b), b)
    f = fused.analyse(x, b, on_so3=False)
    grid = correlation.make_grid("near_identity", on_so3=False)
    w0 = jnp.asarray(rng.normal(size=grid.shape + (2, c)), jnp.float32)

    def s2_whole(w):
        y = correlation.s2_correlate(x, w, grid, b) * scale[:, None, None, None]
        flat = jax.nn.relu(y + shift[:, None, None, None]).reshape((n * c,) + y.shape[2:])
        return jnp.sum(transforms.so3_analysis(flat, l_out) * probe)

    def s2_blocked(w):
        out = fused.pointwise(fused.correlate(f, w, grid, b), scale, shift, l_out,
                              block_floats=block_floats)
        return jnp.sum(out.coeffs * probe)

    assert rel_err(jax.jit(jax.grad(s2_blocked))(w0), jax.grad(s2_whole)(w0)) < 1e-5


@pytest.mark.parametrize("relu", [True, False])
def test_pointwise_gradients_at_odd_sizes(relu):
    """The written-out backward pass where the α fold pads (odd B, L_in < B, L_out odd), with
    and without the ReLU, against autodiff of whole grids."""
    rng = np.random.default_rng(7)
    n, c, b, l_in, l_out = 3, 2, 5, 3, 3
    h = _spectrum(rng, n, c, b, l_in)
    scale, shift = jnp.asarray(rng.normal(size=c)), jnp.asarray(rng.normal(size=c))
    probe = jnp.asarray(rng.normal(size=(2 * l_out - 1, l_out, l_out, 2, n * c)), jnp.float32)
    act = jax.nn.relu if relu else (lambda x: x)

    def whole(coeffs, scale, shift):
        grid = fused.synthesise(h._replace(coeffs=coeffs)) * scale[:, None, None, None] \
            + shift[:, None, None, None]
        flat = act(grid).reshape((n * c,) + grid.shape[2:])
        return jnp.sum(transforms.so3_analysis(flat, l_out) * probe)

    def blocked(coeffs, scale, shift):
        out = fused.pointwise(h._replace(coeffs=coeffs), scale, shift, l_out, relu=relu,
                              block_floats=2 * c * (2 * b) ** 3)
        return jnp.sum(out.coeffs * probe)

    want = jax.grad(whole, (0, 1, 2))(h.coeffs, scale, shift)
    got = jax.jit(jax.grad(blocked, (0, 1, 2)))(h.coeffs, scale, shift)
    for g, w in zip(got, want):
        assert rel_err(g, w) < 1e-5
