"""Matching metrics on hand-made cases, and FPFH + RANSAC on a real 3DMatch pair."""
import numpy as np
from sklearn.neighbors import KDTree

from sphere_jax.data import augment
from sphere_jax.eval import pair_sets, registration
from sphere_jax.features import descriptors
from sphere_jax.registration.fragments import Fragment
from tests.eval import _fixtures


def _fragment(points, key=0):
    points = np.asarray(points, np.float32)
    return Fragment(key, points, None, np.arange(len(points)), KDTree(points))


def _rigid(angle_deg, t):
    a = np.radians(angle_deg)
    out = np.eye(4)
    out[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    out[:3, 3] = t
    return out


def test_rre_rte_hand_made():
    rre, rte = registration.rre_rte(_rigid(30, [0.1, 0, 0]), _rigid(0, [0, 0, 0]))
    assert abs(rre - 30) < 1e-9 and abs(rte - 0.1) < 1e-12


def test_known_matches_give_known_recall_inliers_and_pose():
    """10 keypoints matched one-to-one by their descriptors; 7 of them are where the ground
    truth puts them, 3 are 1 m off: 7 correct, inlier ratio 0.7, and RANSAC recovers T."""
    rng = np.random.default_rng(0)
    t_gt = _rigid(40, [0.5, -0.2, 0.1])
    pi = rng.uniform(-1, 1, (10, 3))
    pj = pair_sets.transform(pi, np.linalg.inv(t_gt))
    pj[7:] += [1.0, 0, 0]
    desc = np.eye(10, dtype=np.float32)
    row = registration.match_pair(_fragment(pi), _fragment(pj, 1), desc, desc, t_gt,
                                  ransac_distance=0.05, ransac_iterations=5000)
    assert row["matches"] == 10 and row["n_correct"] == 7
    assert abs(row["inlier_ratio"] - 0.7) < 1e-12
    assert row["rre_deg"] < 1e-3 and row["rte_m"] < 1e-4 and row["registered"]
    rows = [dict(row), dict(row, errors=np.full(10, 5.0))]       # a second, failed pair
    assert registration.feature_match_recall(rows) == 0.5
    assert registration.feature_match_recall(rows, tau2=0.75) == 0.0
    summary = registration.summarise(rows)
    assert summary["pairs"] == 2 and summary["n_correct"] == 7


def test_registration_recall_follows_the_runs_translation_threshold():
    """RTE must be below the run's threshold (its support radius): 2 cm registers a room's
    pair (0.3 m) but not the bunny's (1.5 cm); RRE must be below 15°."""
    row = dict(errors=np.zeros(1), inlier_ratio=1.0, n_correct=1)
    rows = [dict(row, rre_deg=1.0, rte_m=0.02), dict(row, rre_deg=16.0, rte_m=0.001)]
    assert registration.summarise(rows, rte_ok=0.30)["rr"] == 0.5
    assert registration.summarise(rows, rte_ok=0.015)["rr"] == 0.0


def test_fpfh_ransac_registers_redkitchen_0_5(shared):
    """The issue's acceptance check: FPFH + RANSAC on 3DMatch redkitchen (0, 5)."""
    pair_set = _fixtures.kitchen(shared)
    t_gt = pair_set.transforms[(0, 5)]
    frags = {k: pair_sets.prepare(pair_set, k, voxel=0.02, n_keypoints=5000) for k in (0, 5)}
    desc = {k: descriptors.fpfh(f.points, f.normals, f.keypoints, 0.15)
            for k, f in frags.items()}
    row = registration.match_pair(frags[0], frags[5], desc[0], desc[5], t_gt)
    print(f"redkitchen (0, 5): {row['matches']} matches, {row['n_correct']} correct, "
          f"RRE {row['rre_deg']:.2f} deg, RTE {row['rte_m']:.3f} m")
    assert row["rre_deg"] < 5.0 and row["rte_m"] < 0.1


def test_rotated_variant_keeps_ground_truth_consistent(shared):
    pair_set = _fixtures.kitchen(shared)
    rotated, rot = pair_sets.rotate(pair_set, seed=3)
    assert not np.allclose(rot[0], np.eye(4))
    pi, pj = rotated.load(0), rotated.load(5)
    d, _ = KDTree(pi).query(pair_sets.transform(pj, rotated.transforms[(0, 5)]), k=1)
    d0, _ = KDTree(pair_set.load(0)).query(
        pair_sets.transform(pair_set.load(5), pair_set.transforms[(0, 5)]), k=1)
    assert abs(np.mean(d < 0.05) - np.mean(d0 < 0.05)) < 1e-3 and np.mean(d < 0.05) > 0.3
    assert np.allclose(augment.random_rotations(np.random.default_rng(0)).T @
                       augment.random_rotations(np.random.default_rng(0)), np.eye(3))
