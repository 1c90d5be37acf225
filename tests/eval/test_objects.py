"""Colour + shape recognition: protocols, features and an end-to-end run on synthetic crops."""
import numpy as np
import pytest

from configs import eval_objects
from sphere_jax.data.readers.washington import Sample
from sphere_jax.eval import objects


def _samples():
    out = []
    for cat in ("a", "b"):
        for inst in (1, 2, 3):
            for video in (1, 2, 4):
                for frame in range(1, 7):
                    out.append(Sample(cat, f"{cat}_{inst}", video, frame, "", np.eye(3)))
    return out


def test_protocol_splits_are_disjoint_and_follow_their_rules():
    s = _samples()
    for train, test, labels in objects.splits(s, "category", trials=4, seed=1):
        assert not set(train) & set(test) and len(train) + len(test) == len(s)
        held = {s[k].instance for k in test}
        assert len(held) == 2 and {h[0] for h in held} == {"a", "b"}   # one per category
        assert labels[test[0]] == s[test[0]].category
    (train, test, labels), = objects.splits(s, "instance_lso")
    assert {s[k].video for k in test} == {2} and {s[k].video for k in train} == {1, 4}
    (train, test, labels), = objects.splits(s, "instance_acf", block=2)
    frames = sorted(s[k].frame for k in test if s[k].instance == "a_1" and s[k].video == 1)
    assert frames == [3, 4] and labels[test[0]] == s[test[0]].instance
    with pytest.raises(ValueError, match="protocol"):
        objects.splits(s, "nonsense")


def test_hsv_histogram_of_hand_made_images():
    red = np.zeros((4, 4, 3), np.uint8)
    red[..., 0] = 255
    h = objects.hsv_histogram(red, np.ones((4, 4), bool))
    assert h.shape == (128,) and h[0 * 16 + 3 * 4 + 3] == 1.0         # hue 0, full S and V
    mask = np.zeros((4, 4), bool)
    assert objects.hsv_histogram(red, mask).sum() == 0


@pytest.mark.slow
def test_colour_plus_shape_on_synthetic_crops(tmp_path):
    """Tiny run (4 categories × 3 instances): both features together recognise instances
    across videos better than colour alone, with the shipped LEAD bundle as shape feature."""
    c = eval_objects.get_config("tiny")
    c.protocols = "instance_lso"
    rows, md = objects.run(c, str(tmp_path), progress=False)
    acc = {(r["features"], r["classifier"]): r["accuracy"] for r in rows}
    print(md)
    assert (tmp_path / "objects.csv").read_text().startswith("protocol,features,classifier")
    for clf in ("GNB", "LR"):
        assert acc[("colour+shape", clf)] >= acc[("colour", clf)]
        assert acc[("colour+shape", clf)] > 0.9
