"""Shapes oriented once: each split turned into the orienter's frames, kept in the cache, and
a training split of turned copies for the classifier trained on turned shapes."""
import numpy as np
import pytest

from sphere_jax.data import augment, oriented


class PcaOrienter:
    """Principal axes as the frame (signs fixed by the third moment): equivariant for shapes
    without symmetry, and cheap; counts the shapes it orients."""
    key = "pca"

    def __init__(self):
        self.seen = 0

    def frames(self, shapes_BxNx3):
        self.seen += len(shapes_BxNx3)
        c = shapes_BxNx3.mean(1, keepdims=True)
        x = shapes_BxNx3 - c
        _, vecs = np.linalg.eigh(np.einsum("bni,bnj->bij", x, x))
        skew = (np.einsum("bni,bik->bnk", x, vecs) ** 3).sum(1)             # [B, 3]
        vecs = vecs * np.sign(skew)[:, None, :]
        vecs[:, :, 2] = np.cross(vecs[:, :, 0], vecs[:, :, 1])
        return c, vecs


class Source:
    """The fields of a ShapeSource that oriented_source reads."""
    root, orientation = "/nowhere", None

    def __init__(self, splits):
        self.splits = splits

    def split_rule(self):
        return "test: rule"


@pytest.fixture
def source(monkeypatch, tmp_path):
    monkeypatch.setenv("SPHERE_JAX_DATA", str(tmp_path))
    rng = np.random.default_rng(0)
    scale = np.array([3.0, 2.0, 1.0])                       # distinct principal axes
    make = lambda n: [(rng.normal(size=(64, 3)) ** 3) * scale for _ in range(n)]
    return Source({"train": (make(5), np.arange(5)), "test": (make(3), np.arange(3))})


def test_each_shape_is_oriented_once_and_cached(source):
    orienter = PcaOrienter()
    out = oriented.oriented_source(source, orienter, progress=False)
    assert orienter.seen == 8
    shape, turned = source.splits["test"][0][1], out.splits["test"][0][1]
    c, f = orienter.frames(shape[None])
    np.testing.assert_allclose(turned, (shape - c[0]) @ f[0], atol=1e-5)
    again = PcaOrienter()
    kept = oriented.oriented_source(source, again, progress=False)
    assert again.seen == 0                                   # read from the cache
    np.testing.assert_array_equal(kept.splits["test"][0][1], turned)
    assert out.orientation == {"orienter": "pca", "rotated_copies": 0}


def test_turned_copies_of_training_shapes_land_on_the_canonical_ones(source):
    """With an equivariant orienter the k turned copies of a shape, oriented, are the shape
    oriented — the copies are turns of the training shapes, labels repeated."""
    out = oriented.oriented_source(source, PcaOrienter(), rotated_copies=3, seed=4,
                                   progress=False)
    shapes, labels = out.splits["train"]
    assert len(shapes) == 15 and labels.tolist() == np.repeat(np.arange(5), 3).tolist()
    plain = oriented.oriented_source(source, PcaOrienter(), progress=False).splits["train"][0]
    for k, s in enumerate(shapes):
        np.testing.assert_allclose(s, plain[k // 3], atol=1e-4)
    turns = oriented.seeded_turns(15, [4, 1])
    assert not np.allclose(turns[0], turns[1])
    np.testing.assert_allclose(turns @ turns.transpose(0, 2, 1), np.eye(3)[None].repeat(15, 0),
                               atol=1e-9)
    assert len(out.splits["test"][0]) == 3                   # only training shapes are copied


def test_turn_rotates_each_shape_by_its_rotation():
    rng = np.random.default_rng(1)
    r = augment.random_rotations(rng, 2)
    shapes = [rng.normal(size=(4, 3)), rng.normal(size=(6, 3))]
    for s, t, rot in zip(shapes, oriented.turn(shapes, r), r):
        np.testing.assert_allclose(t, (rot @ s.T).T)
