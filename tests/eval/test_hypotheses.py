"""Frame hypotheses: the first is Compass's frame and LEAD under it is ``lead@compass``; the
others stand apart; a correspondence is recalled when any pair of hypotheses repeats."""
import numpy as np
import pytest

from sphere_jax.bundles import inference
from sphere_jax.data import demo
from sphere_jax.eval import hypotheses
from sphere_jax.features import methods, modes
from sphere_jax.models import shipped
from sphere_jax.registration.fragments import fragment
from sphere_jax.spherical import so3

BUNDLES = {k: shipped.bundle_path(k) for k in ("lead", "compass")}


@pytest.fixture(scope="module")
def frag():
    (src, _), _ = demo.fragment_pair()
    return fragment("a", src, 0.02, np.random.default_rng(0), n_keypoints=48)


def test_first_mode_is_compass_frame_and_the_next_stand_apart(frag):
    compass = inference.load_bundle("compass")
    m, valid = compass.orient_modes(frag.points, frag.keypoints, 3, radius=0.3,
                                    on_invalid="mask")
    frames, ok = compass.orient(frag.points, frag.keypoints, radius=0.3, on_invalid="mask")
    assert np.array_equal(valid, ok) and valid.sum() > 40
    m = m[valid].astype(np.float64)
    first = np.degrees(so3.geodesic_distance_np(m[:, 0], frames[valid].astype(np.float64)))
    assert first.max() < 0.1
    for a, b in ((0, 1), (0, 2), (1, 2)):
        # peaks 45° apart; each later one refined within 22.5° of its own peak
        assert np.degrees(so3.geodesic_distance_np(m[:, a], m[:, b])).min() > 20.0


def test_lead_under_the_first_mode_is_lead_at_compass(frag):
    under = modes.lead_modes(0.3, BUNDLES, k=2)([frag])[0]
    plain = methods.descriptor("lead@compass", 0.3, BUNDLES)(frag)
    assert under.shape == (len(frag.keypoints), 2, plain.shape[1])
    ok = np.isfinite(plain).all(1)
    assert np.array_equal(ok, np.isfinite(under).all((1, 2)))
    scale = np.abs(plain[ok]).max()
    assert np.abs(under[ok, 0] - plain[ok]).max() < 1e-4 * scale
    assert np.abs(under[ok, 1] - plain[ok]).max() > 0.1 * scale


def test_frame_recall_counts_any_repeating_pair_of_hypotheses():
    rot = so3.euler_to_matrix_np(0.4, 1.0, -0.3)
    right = so3.euler_to_matrix_np(*np.random.default_rng(0).uniform(0, 3, (3, 4)))  # [4,3,3]
    wrong = right @ so3.euler_to_matrix_np(0.0, np.pi, 0.0)                          # flipped
    fi = np.stack([wrong, right], 1)                       # the right frame second in i
    fj = np.stack([rot.T @ right, rot.T @ wrong], 1)       # first in j
    fj[3] = rot.T @ right[3] @ so3.euler_to_matrix_np(0.5, 0.5, 0.5)  # the last: neither
    assert hypotheses.frame_recall(fi, fj, rot, 1) == 0.0
    assert hypotheses.frame_recall(fi, fj, rot, 2) == 0.75
