"""LRF repeatability: hand-made cases and the hand-crafted LRFs on real bunny scan pairs."""
import numpy as np
import pytest

from sphere_jax.data import augment
from sphere_jax.eval import pair_sets, repeatability
from sphere_jax.features import methods
from sphere_jax.registration.fragments import Fragment
from tests.eval import _fixtures


def test_identical_frames_are_repeatable_and_perpendicular_ones_not():
    pts = np.random.default_rng(0).uniform(-1, 1, (200, 3)).astype(np.float32)
    from sklearn.neighbors import KDTree
    frag = Fragment(0, pts, None, np.arange(50), KDTree(pts))
    same = lambda f, idx: np.repeat(np.eye(3)[None], len(idx), 0)
    r = repeatability.pair_repeatability(same, frag, frag, np.eye(4), 0.01)
    assert r["n"] == 50 and r["rep"] == 1.0 and r["mean_angle_deg"] < 1e-6
    turn = np.eye(4)
    turn[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]                  # 90° about z
    moved = Fragment(1, pair_sets.transform(pts, np.linalg.inv(turn)).astype(np.float32),
                            None, np.arange(50), None)
    moved.tree = KDTree(moved.points)
    r = repeatability.pair_repeatability(same, frag, moved, turn, 0.01)
    assert r["n"] == 50 and r["rep"] == 0.0 and abs(r["mean_angle_deg"] - 90) < 1e-4
    nan = lambda f, idx: np.full((len(idx), 3, 3), np.nan)
    assert repeatability.pair_repeatability(nan, frag, frag, np.eye(4), 0.01)["rep"] == 0.0


@pytest.fixture(scope="module")
def bunny_pair(request):
    shared = request.getfixturevalue("shared")
    s = _fixtures.bunny(shared)
    pair = ("bun000.ply", "bun045.ply")
    assert pair in s.transforms, sorted(s.transforms)
    frags = {k: pair_sets.prepare(s, k, voxel=0.001, n_keypoints=1000) for k in pair}
    return frags, s.transforms[pair], pair


@pytest.mark.parametrize("name", ["flare", "shot"])
def test_real_bunny_repeatability_above_chance_and_rotation_invariant(bunny_pair, name):
    frags, t, (i, j) = bunny_pair
    orient = methods.lrf(name, radius=0.015)
    rep = repeatability.pair_repeatability(orient, frags[i], frags[j], t, 0.001)
    rot = augment.random_rotations(np.random.default_rng(7))
    turned = _fixtures.rotated_copy(frags[j], rot)
    rot4 = np.eye(4)
    rot4[:3, :3] = rot
    rep_rot = repeatability.pair_repeatability(orient, frags[i], turned,
                                               t @ np.linalg.inv(rot4), 0.001)
    print(f"{name}: bunny {i}-{j}: Rep {rep['rep']:.3f} on {rep['n']} keypoints "
          f"(scan j rotated: {rep_rot['rep']:.3f}), mean angle {rep['mean_angle_deg']:.1f} deg")
    assert rep["n"] > 200
    assert rep["rep"] > 0.1
    assert abs(rep["rep"] - rep_rot["rep"]) < 0.03


def test_an_adaptation_of_a_retrained_bundle_is_set_aside_not_resumed(tmp_path):
    """The adapted-frames run's own adaptation folder, left by a bundle since retrained, is
    moved aside (kept) so that the rerun adapts the new weights; one of the same weights
    stays to be resumed."""
    import json
    from types import SimpleNamespace
    from sphere_jax.bundles import store
    trained = SimpleNamespace(variables={"params": {"w": np.arange(4, dtype=np.float32)}})
    mine = store.variables_digest(trained.variables)
    folder = tmp_path / "adapted_compass"
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({"train": {"started_from": mine}}))
    repeatability._set_aside_if_stale(str(folder), trained)
    assert folder.is_dir()                                   # the same weights: kept there
    retrained = SimpleNamespace(variables={"params": {"w": np.arange(4, dtype=np.float32) + 1}})
    repeatability._set_aside_if_stale(str(folder), retrained)
    assert not folder.exists()
    assert json.loads((tmp_path / f"adapted_compass-of-{mine}" / "config.json").read_text())
