import os

import pytest

SHARED = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", "..", "shared",
                                       "data"))


@pytest.fixture(scope="session")
def shared():
    """Root of the real scans in ``../shared/data`` (skips where the checkout has none)."""
    if not os.path.isdir(SHARED):
        pytest.skip("real data ../shared/data not present")
    return SHARED
