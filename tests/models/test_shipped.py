"""The shipped bundles' outputs against a fixture recorded before the last refactor
(``shipped_outputs.py``): a change of structure must not change a single output."""
import pytest
import numpy as np

import sphere_jax
from tests.models import shipped_outputs


@pytest.mark.slow
def test_shipped_bundles_reproduce_the_fixture():
    want = np.load(shipped_outputs.FIXTURE)
    got = shipped_outputs.compute()
    assert sorted(got) == sorted(want.files)
    for name in want.files:
        # Bit for bit on the machine that recorded it; XLA may pick other kernels on another
        # CPU, hence the round-off tolerance (a real change moves descriptors by > 1e-2).
        err = np.abs(got[name] - want[name]).max() / np.abs(want[name]).max()
        assert err <= 1e-5, f"{name}: relative difference {err:.2e}"
    frames = got["compass_orient"]
    assert np.allclose(frames.transpose(0, 2, 1) @ frames, np.eye(3), atol=1e-5)
    # What register runs for LEAD (Compass): both networks in one call on one draw of patches.
    bundle = lambda name: sphere_jax.load_bundle(shipped_outputs.bundle(name))
    joint = bundle("lead").describe(shipped_outputs.cloud(), shipped_outputs.KEYPOINTS,
                                    radius=shipped_outputs.RADIUS, workers=1,
                                    frames=bundle("compass"), whiten="compass")
    np.testing.assert_array_equal(joint, got["lead_compass_describe_whitened"])
