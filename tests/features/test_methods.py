"""The benchmark's method table: several fragments in one stream describe as one at a time; the
ground-truth diagnostics describe a pair in one pose."""
import numpy as np
import pytest

from sphere_jax.bundles import inference
from sphere_jax.features import methods
from sphere_jax.models import shipped
from tests.eval import _fixtures
from tests.eval._fixtures import relative_difference as _relative

BUNDLES = {k: shipped.bundle_path(k) for k in ("lead", "compass")}


@pytest.fixture(scope="module")
def moved_pair():
    return _fixtures.moved_pair()


@pytest.mark.slow
def test_fragments_in_one_stream_describe_as_one_at_a_time(moved_pair):
    """LEAD in Compass's frames of two fragments, chained so that chunks straddle them (13
    patches each, 48 + 48 keypoints, a too-small support masked NaN in the second), equal each
    fragment described alone: each keeps its own patch draw, and only the GEMMs' blocking
    over another chunk's rows differs (6e-7 measured; the speed issue's bar is 1e-5)."""
    f, g, _ = moved_pair
    sparse = g.points.copy()
    sparse[g.keypoints[5]] += 40.0                  # a keypoint with no support
    g = type(g)(g.key, sparse, g.normals, g.keypoints, None)
    together = methods.descriptor_of_many("lead@compass", 0.30, BUNDLES, chunk=13)([f, g])
    alone = methods.descriptor("lead@compass", 0.30, BUNDLES, chunk=13)
    for both, one in zip(together, (alone(f), alone(g))):
        np.testing.assert_allclose(both, one, rtol=0, atol=1e-5)
    assert np.isfinite(together[0]).all() and np.isnan(together[1][5]).all()   # no match
    assert np.isfinite(np.delete(together[1], 5, axis=0)).all()


def test_shot_gt_bins_both_scans_of_a_pair_alike(moved_pair):
    """SHOT reads exact neighbourhoods, so in the ground-truth frames the moved scan's
    histograms equal the scan's own but for the float32 round-off of the moved points (a
    neighbour at the support's edge may fall either side: 0.6 % measured); given the inverse
    rotation (the other convention) they do not."""
    f, g, t = moved_pair
    diag = methods.ground_truth_frames("shot_gt", 0.30)
    d_f, d_g = diag.describe_pair(f, g, t)
    _, wrong = diag.describe_pair(f, g, np.linalg.inv(t))
    same, other = _relative(d_g, d_f), _relative(wrong, d_f)
    print(f"relative difference {same:.4f}, the other convention {other:.3f}")
    assert same < 0.02 and other > 0.3


@pytest.mark.slow
def test_lead_gt_gives_corresponding_patches_one_pose(moved_pair):
    """LEAD's maps of the moved scan, turned by the ground truth, equal the scan's own up to
    the patch resampling (the two clouds' KD-trees list neighbours in different orders) and
    the network's equivariance error, while in the identity frame or turned the other way
    they differ by a full rotation."""
    f, g, t = moved_pair
    diag = methods.ground_truth_frames("lead_gt", 0.30, BUNDLES)
    d_f, d_g = diag.describe_pair(f, g, t)
    rows = np.linalg.norm(d_f, axis=1) > 0                     # described keypoints
    assert rows.sum() > 40
    # The floor: the same scan described from another random draw of its patches.
    eye = np.broadcast_to(np.eye(3, dtype=np.float32), (len(f.keypoints), 3, 3))
    lead = inference.cached_bundle(BUNDLES["lead"])
    white = "compass" if "compass" in lead.whitenings else None     # as lead_gt whitens
    redrawn, _ = lead.describe(f.points, f.keypoints, radius=0.30, frames=eye, seed=1,
                               on_invalid="mask", whiten=white)
    unturned, _ = lead.describe(g.points, g.keypoints, radius=0.30, frames=eye,
                                on_invalid="mask", whiten=white)
    _, wrong = diag.describe_pair(f, g, np.linalg.inv(t))
    floor, turned = _relative(redrawn[rows], d_f[rows]), _relative(d_g[rows], d_f[rows])
    unturned, wrong = _relative(unturned[rows], d_f[rows]), _relative(wrong[rows], d_f[rows])
    print(f"relative error: redrawn {floor:.3f}, turned {turned:.3f}, unturned {unturned:.3f}, "
          f"turned the wrong way {wrong:.3f}")
    # Turned keeps the network's own equivariance error on top of the redraw (the patch
    # signal is sampled on a grid that does not turn with the patch): a few per cent, which
    # does not shrink with the floor, against a full rotation's 1.3-1.6 unturned or turned the
    # wrong way. Whitened as lead_gt is (the weak directions weigh as much as the strong),
    # measured on the redkitchen scan: redrawn 0.045, turned 0.091, unturned 1.32, wrong 1.34
    # (unwhitened: 0.018 / 0.042).
    assert floor < turned < 0.12 and min(unturned, wrong) > 10 * turned


def test_ground_truth_diagnostics_are_refused_outside_the_pair_benchmark():
    with pytest.raises(ValueError, match="lead_gt"):
        methods.descriptor("lead_gt", 0.3, BUNDLES)
    with pytest.raises(ValueError, match="needs bundle"):
        methods.ground_truth_frames("lead_gt", 0.3, {})
    with pytest.raises(ValueError, match="name must be one of"):
        methods.ground_truth_frames("lead", 0.3, BUNDLES)
