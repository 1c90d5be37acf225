"""Mutual nearest neighbours: a hand-made case, the blocked search against all distances, and
undescribed (NaN) rows left out."""
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
    # Exact ties (a base set twice) go to the first copy, as with the distances themselves.
    assert np.array_equal(matching.nearest(q, np.concatenate([b, b]), rows=7), full)


def test_undescribed_rows_never_match_where_a_zero_row_would_take_them():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(300, 84))                    # LEAD's 84 degrees of freedom
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = a + 0.2 * rng.normal(size=a.shape)            # noisy copies, often over 1 apart
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    ia, ib = matching.mutual_matches(a, b)
    holed = a.copy()
    holed[5] = np.nan                                  # keypoint 5: no descriptor
    ja, jb = matching.mutual_matches(holed, b)
    keep = ia != 5
    assert np.array_equal(ja, ia[keep]) and np.array_equal(jb, ib[keep])
    zeroed = a.copy()
    zeroed[5] = 0                                      # the old fill: nearest to every far row
    za, _ = matching.mutual_matches(zeroed, b)
    assert len(za) < 0.5 * len(ja)                    # 115 of 281 here
    assert len(matching.mutual_matches(np.full((3, 84), np.nan), b)[0]) == 0


def _loop_matches_over_hypotheses(a, b):
    """Mutual nearest neighbours under the smallest distance over hypothesis pairs, by loops."""
    d = np.full((len(a), len(b)), np.inf)
    for i in range(len(a)):
        for j in range(len(b)):
            if np.isfinite(a[i]).all() and np.isfinite(b[j]).all():
                d[i, j] = min(np.sum((x - y) ** 2) for x in a[i] for y in b[j])
    pairs = [(i, int(np.argmin(d[i]))) for i in range(len(a)) if np.isfinite(d[i]).any()]
    pairs = [(i, j) for i, j in pairs if int(np.argmin(d[:, j])) == i]
    return np.asarray(pairs, np.int64).reshape(-1, 2)


@pytest.mark.parametrize("h", [1, 2, 3])
def test_matches_over_frame_hypotheses_equal_the_loop_reference(h):
    rng = np.random.default_rng(h)
    a = rng.normal(size=(30, h, 6))
    b = np.concatenate([a[:20] + 0.05 * rng.normal(size=(20, h, 6)),
                        rng.normal(size=(15, h, 6))])
    b = b[:, rng.permutation(h)]                  # the hypotheses in another order
    a[4], b[7] = np.nan, np.nan                   # undescribed keypoints never match
    ia, ib = matching.mutual_matches(a, b)
    got = np.stack([ia, ib], 1)
    np.testing.assert_array_equal(got, _loop_matches_over_hypotheses(a, b))
    assert len(got) >= 18                         # the 20 planted pairs, less the NaN ones
    # blocks of a few queries give the same answer as one block
    assert np.array_equal(matching.nearest(a[5:], b[8:], rows=4),
                          matching.nearest(a[5:], b[8:], rows=1000))
