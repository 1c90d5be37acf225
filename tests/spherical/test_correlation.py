import numpy as np
import pytest

from sphere_jax.spherical import correlation, transforms
from tests import reference
from tests.reference import rel_err


@pytest.mark.parametrize("kind", ["near_identity", "equatorial"])
def test_s2_correlation_matches_direct_sum(kind):
    rng = np.random.default_rng(0)
    b_in, b_out, c, d = 5, 4, 2, 3
    grid = correlation.make_grid(kind, on_so3=False, bandwidth=b_in)
    coeffs = reference.random_s2_coeffs(rng, (c,), b_in)
    w = rng.normal(size=grid.shape + (c, d))
    got = correlation.s2_correlate(transforms.s2_ifft(coeffs, b_in)[None],
                                   w.astype(np.float32), grid, b_out)[0]
    # Degrees ≥ b_out are cut by the output band limit: correlate the truncated input.
    expect = reference.correlate_direct(reference.s2_eval_rot, coeffs[:, :b_out, :b_out], w,
                                        grid, b_out)
    assert rel_err(got, expect) < 1e-5


@pytest.mark.parametrize("kind", ["near_identity", "equatorial"])
def test_so3_correlation_matches_direct_sum(kind):
    rng = np.random.default_rng(1)
    b_in, b_out, c, d = 4, 3, 2, 2
    grid = correlation.make_grid(kind, on_so3=True, bandwidth=b_in)
    coeffs = reference.random_so3_coeffs(rng, (c,), b_in)
    w = rng.normal(size=grid.shape + (c, d))
    got = correlation.so3_correlate(transforms.so3_ifft(coeffs, b_in)[None],
                                    w.astype(np.float32), grid, b_out)[0]
    lo = b_in - b_out
    expect = reference.correlate_direct(reference.so3_eval_rot,
                                        coeffs[:, :b_out, lo:2 * b_in - 1 - lo, :b_out], w,
                                        grid, b_out)
    assert rel_err(got, expect) < 1e-5


def test_bad_inputs():
    grid = correlation.make_grid("near_identity", on_so3=True)
    w = np.zeros(grid.shape + (3, 2), np.float32)
    x = np.zeros((1, 3, 8, 8, 8), np.float32)
    with pytest.raises(ValueError, match="b_out=5 > b_in=4"):
        correlation.so3_correlate(x, w, grid, 5)
    with pytest.raises(ValueError, match="C_in=3"):
        correlation.so3_correlate(x[:, :2], w, grid, 4)
    with pytest.raises(ValueError, match="kernel weights must have shape"):
        correlation.so3_correlate(x, w[0], grid, 4)
    with pytest.raises(ValueError, match="grid must be"):
        correlation.make_grid("polar", on_so3=False)
