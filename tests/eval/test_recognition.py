"""Recognition: IoU, PR/AUC and grouping on hand-made cases; Saliency Boost on synthetic frames."""

import numpy as np
import pytest

from sphere_jax.data import augment
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import rgbd
from sphere_jax.eval import labelled, recognition, saliency
from sphere_jax.registration.estimation import kabsch


def test_box_iou_hand_made():
    assert recognition.box_iou([0, 0, 9, 9], [0, 0, 9, 9]) == 1.0
    assert recognition.box_iou([0, 0, 9, 9], [10, 10, 19, 19]) == 0.0
    assert abs(recognition.box_iou([0, 0, 9, 9], [5, 0, 14, 9]) - 50 / 150) < 1e-12


def test_precision_recall_and_auc_hand_made():
    # Scores 5, 4, 3, 2 with correct, wrong, correct, wrong; 4 objects to find.
    p, r = recognition.precision_recall([3, 5, 2, 4], [True, True, False, False], 4)
    np.testing.assert_allclose(p, [1.0, 0.5, 2 / 3, 0.5])
    np.testing.assert_allclose(r, [0.25, 0.25, 0.5, 0.5])
    # Trapezoids: 0→0.25 at precision 1; 0.25→0.25 nothing; 0.25→0.5 between 0.5 and 2/3.
    assert abs(recognition.pr_auc(p, r) - (0.25 + 0.25 * (0.5 + 2 / 3) / 2)) < 1e-12
    p, r = recognition.precision_recall([1, 1], [True, True], 2)
    assert recognition.pr_auc(p, r) == 1.0


def test_consistency_grouping_finds_the_rigid_set_among_outliers():
    rng = np.random.default_rng(0)
    model = rng.uniform(-0.1, 0.1, (40, 3))
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = augment.random_rotations(rng), [0.3, -0.2, 1.0]
    scene = model @ t[:3, :3].T + t[:3, 3]
    scene[25:] = rng.uniform(-0.5, 0.5, (15, 3)) + [0, 0, 1]         # 15 wrong matches
    groups = recognition.consistency_groups(model, scene, 0.005, min_size=3)
    assert sorted(groups[0]) == list(range(25))
    est = kabsch(model[groups[0]], scene[groups[0]])
    assert np.abs(est - t).max() < 1e-9


@pytest.fixture(scope="module")
def frames():
    return rgbd.read_object_frames(synthetic.default_root("objects"))


def test_saliency_keeps_objects_and_drops_keypoints(frames):
    """On every synthetic table-top frame, the salient pixels hold most of each object's
    pixels while the salient scene yields far fewer keypoints."""
    kept_obj, kept_px, kp_ratio = [], [], []
    for fr in frames[::3]:
        mask = saliency.salient_mask(saliency.spectral_residual(fr.color))
        kept_obj.append(mask[fr.mask > 0].mean())
        kept_px.append(mask.mean())
        pts, px = fr.points()
        full = labelled.make_fragment(pts, 0.03, 0.005)
        boosted = labelled.make_fragment(pts[mask[px[:, 0], px[:, 1]]], 0.03, 0.005)
        kp_ratio.append(len(boosted.keypoints) / len(full.keypoints))
    print(f"objects kept {np.mean(kept_obj):.2f}, pixels kept {np.mean(kept_px):.2f}, "
          f"keypoints kept {np.mean(kp_ratio):.2f}")
    assert np.mean(kept_obj) > 0.8 and min(kept_obj) > 0.5
    assert np.mean(kp_ratio) < 0.6


def test_spectral_residual_rejects_bad_images():
    with pytest.raises(ValueError, match="rgb"):
        saliency.spectral_residual(np.zeros((2, 2, 3)))


@pytest.mark.slow
def test_recognition_finds_objects_on_synthetic_frames(frames):
    """SHOT with the database of the first two views per scene: above-chance AUC."""
    from sphere_jax.features import methods
    model, test = labelled.split_frames(frames, 2)
    assert len(model) == 8 and len(test) == 16
    db = labelled.build_database(model, 0.03, 0.005)
    rows, _ = recognition.evaluate(test[::4], db, {"shot": methods.descriptor("shot", 0.08)},
                                   0.03, 0.005, 0.3, 0.01, max_depth=1.6, progress=False)
    print(rows[0])
    assert rows[0]["correct"] >= 3 and rows[0]["auc"] > 0.2
