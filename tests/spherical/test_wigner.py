import numpy as np
import pytest

from sphere_jax.spherical import so3, wigner
from tests import reference


def test_tables_match_closed_form_at_small_degrees():
    betas = np.array([0.0, 0.3, 1.2, np.pi / 2, 2.9, np.pi])
    lmax = 7
    np.testing.assert_allclose(wigner.wigner_d_dense(lmax, betas),
                               reference.wigner_d_explicit_table(lmax, betas), atol=1e-12)
    # Sign convention (s2cnn / lie_learn): d^1_{10}(β) = -sin β / √2.
    assert abs(wigner.wigner_d(1, 0.7)[2, 1] + np.sin(0.7) / np.sqrt(2)) < 1e-14


@pytest.mark.slow
def test_stable_and_orthogonal_up_to_bandwidth_64():
    for l in [40, 63]:
        d = wigner.wigner_d(l, np.array([0.1, 1.3, 3.0]))
        err = np.abs(d @ d.transpose(0, 2, 1) - np.eye(2 * l + 1)).max()
        assert err < 1e-12
    # Orthogonality over β with the SOFT quadrature: Σ_j w_j d^l_{mn} d^l'_{mn} = 2/(2l+1) δ.
    b = 64
    d = wigner.wigner_d_dense(b, so3.grid_beta(b))[:, :, b - 1 + 3, b - 1 - 2]  # m=3, n=-2
    gram = np.einsum("j,jl,jk->lk", so3.quadrature_weights(b), d, d)
    expect = np.diag(np.where(np.arange(b) >= 3, 2 / (2 * np.arange(b) + 1), 0.0))
    assert np.abs(gram - expect).max() < 1e-12


def test_wigner_D_is_a_representation():
    rng = np.random.default_rng(1)
    e1, e2 = rng.uniform(0.2, 2.5, 3), rng.uniform(0.2, 2.5, 3)
    r12 = so3.euler_to_matrix_np(*e1) @ so3.euler_to_matrix_np(*e2)
    a, b, g = reference._matrix_to_euler_np(r12[None])
    for l in [1, 4, 9]:
        lhs = wigner.wigner_D(l, a[0], b[0], g[0])
        rhs = wigner.wigner_D(l, *e1) @ wigner.wigner_D(l, *e2)
        assert np.abs(lhs - rhs).max() < 1e-12


def test_jax_tables_match_numpy():
    beta = np.array([0.2, 1.7])
    got = np.asarray(wigner.wigner_d_jax(6, beta))
    np.testing.assert_allclose(got, wigner.wigner_d_dense(6, beta), atol=2e-6)
