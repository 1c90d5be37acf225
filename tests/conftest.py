import pytest

from sphere_jax import paths


@pytest.fixture(scope="session")
def shared():
    """Root of the real scans (:func:`sphere_jax.paths.real_data_root`; skips without them)."""
    root = paths.real_data_root()
    if root is None:
        pytest.skip("real data (../shared/data or $SPHERE_JAX_REAL_DATA) not present")
    return root
