"""Mutual nearest neighbours: a hand-made case, and the blocked search against all distances."""
import numpy as np
import pytest

from sphere_jax.registration import matching


def test_mutual_matches_hand_made():
    a = np.array([[0.0], [1.0], [10.0]])
    b = np.array([[0.1], [9.5], [20.0]])
    ia, ib = matching.mutual_matches(a, b)
    assert ia.tolist() == [0, 2] and ib.tolist() == [0, 1]
    with pytest.raises(ValueError, match="same D"):
        matching.mutual_matches(a, np.zeros((3, 2)))
    empty = matching.mutual_matches(np.zeros((0, 1)), b)
    assert [len(x) for x in empty] == [0, 0]


def test_blocked_nearest_matches_the_full_distance_matrix():
    rng = np.random.default_rng(0)
    q, b = rng.normal(size=(300, 32)), rng.normal(size=(200, 32))
    full = np.argmin(np.linalg.norm(q[:, None] - b[None], axis=2), axis=1)
    assert np.array_equal(matching.nearest(q, b, rows=7), full)
