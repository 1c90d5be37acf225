import numpy as np
import jax
import jax.numpy as jnp
import pytest

from sphere_jax.spherical import so3, soft_argmax


def planted_map(b, peak, width=1.5, seed=0):
    """Gaussian bump (circular in α, γ) at fractional grid index ``peak`` plus weak noise."""
    n = 2 * b
    i = np.arange(n)
    d_b = i - peak[0]
    d_a = (i - peak[1] + n / 2) % n - n / 2
    d_g = (i - peak[2] + n / 2) % n - n / 2
    d2 = d_b[:, None, None] ** 2 + d_a[None, :, None] ** 2 + d_g[None, None, :] ** 2
    noise = 0.05 * np.random.default_rng(seed).normal(size=(n, n, n))
    return (8.0 * np.exp(-d2 / (2 * width ** 2)) + noise).astype(np.float32)


@pytest.mark.parametrize("peak", [(5.3, 7.6, 2.2), (9.0, 0.3, 15.7)])
def test_recovers_planted_peak(peak):
    b = 8
    idx = soft_argmax.soft_argmax_indices(jnp.asarray(planted_map(b, peak)))
    offset = np.asarray(idx) - np.asarray(peak)
    offset[1:] = (offset[1:] + b) % (2 * b) - b                       # circular α, γ
    assert np.abs(offset).max() < 0.15
    rot = soft_argmax.soft_argmax_rotation(jnp.asarray(planted_map(b, peak)))
    expect = so3.euler_to_matrix(*soft_argmax.indices_to_euler(np.asarray(peak), b))
    assert float(so3.geodesic_distance(rot, expect)) < 0.05


def test_window_ignores_far_secondary_mode():
    b = 8
    x = planted_map(b, (4.0, 3.0, 3.0)) + 0.9 * planted_map(b, (12.0, 11.0, 11.0), seed=1)
    idx = soft_argmax.soft_argmax_indices(jnp.asarray(x), window=4)
    assert np.abs(np.asarray(idx) - [4.0, 3.0, 3.0]).max() < 0.15


def test_parzen_window_shape():
    d = jnp.array([0.0, 2.0, 4.0, 6.0, 8.0, 9.0])
    w = soft_argmax.parzen_window(d, 8.0)
    np.testing.assert_allclose(w, [1.0, 1 - 6 / 16 * 0.75, 0.25, 2 / 64, 0.0, 0.0], atol=1e-6)


def test_gradients_are_finite_and_move_the_estimate():
    x = jnp.asarray(planted_map(6, (4.2, 5.0, 6.5)))
    g = jax.grad(lambda m: soft_argmax.soft_argmax_rotation(m)[0, 0])(x)
    assert bool(jnp.all(jnp.isfinite(g))) and float(jnp.abs(g).max()) > 0
    batched = jax.vmap(soft_argmax.soft_argmax_rotation)(jnp.stack([x, x]))
    assert batched.shape == (2, 3, 3)


def test_bad_input():
    with pytest.raises(ValueError, match="one SO\\(3\\) map"):
        soft_argmax.soft_argmax_indices(jnp.zeros((2, 8, 8, 8)))
    x = np.zeros((8, 8, 8), np.float32)
    x[1, 2, 3] = np.nan
    with pytest.raises(ValueError, match="must be finite; got 1 non-finite"):
        soft_argmax.soft_argmax_rotation(x)


def rotation_bump(b, rot_33, kappa=12.0):
    """A map peaked at rotation ``rot_33``: exp(κ (cos θ - 1)) of each cell's geodesic angle
    θ to it (a von Mises-Fisher bump on SO(3), free of grid-index artefacts)."""
    grid = so3.so3_grid_matrices(b)
    cos = (np.einsum("jagxy,xy->jag", grid, rot_33) - 1.0) / 2.0
    return np.exp(kappa * (cos - 1.0))


def test_modes_find_two_planted_rotations_strongest_first():
    b = 12                                      # Compass's: 15° cells
    r1 = so3.euler_to_matrix_np(0.7, 1.1, 2.3)
    r2 = r1 @ so3.euler_to_matrix_np(0.0, np.pi, 0.0)         # the same frame, half a turn on
    x = (8.0 * (rotation_bump(b, r1) + 0.8 * rotation_bump(b, r2))).astype(np.float32)
    rots, values = soft_argmax.soft_argmax_modes(jnp.asarray(x), 3)
    rots = np.asarray(rots, np.float64)
    assert np.degrees(so3.geodesic_distance_np(rots[0], r1)) < 5.0
    assert np.degrees(so3.geodesic_distance_np(rots[1], r2)) < 5.0
    assert values[0] > values[1] > values[2]
    # the first mode is the soft arg-max itself; every mode is a rotation
    one = np.asarray(soft_argmax.soft_argmax_rotation(jnp.asarray(x)))
    assert np.abs(rots[0] - one).max() < 1e-5
    assert np.abs(rots @ rots.transpose(0, 2, 1) - np.eye(3)).max() < 1e-4
    # and no later mode lies within the separation of an earlier one
    for i in range(3):
        for j in range(i):
            assert np.degrees(so3.geodesic_distance_np(rots[i], rots[j])) > 30.0


def test_modes_beyond_the_separated_cells_repeat_the_last():
    b = 4                                       # 512 cells: 90° apart leaves only a few modes
    x = rotation_bump(b, so3.euler_to_matrix_np(0.3, 0.9, 0.1)).astype(np.float32)
    rots, values = jax.jit(lambda m: soft_argmax.soft_argmax_modes(m, 40, 90.0))(x)
    assert np.isfinite(np.asarray(rots)).all()
    assert np.isneginf(np.asarray(values)[-1])
    assert np.abs(np.asarray(rots)[-1] - np.asarray(rots)[-2]).max() == 0.0
