"""The scans' patch source: copies drawn from a second sampling of the support or from
another scan of the scene (by the ground truth's poses)."""

import numpy as np
import pytest

from sphere_jax.data import patch_source, scan_roots


def test_copies_drawn_from_the_whole_support_are_a_second_sampling(tmp_path):
    """'patch' copies (the seed's) reuse the patch's own points; 'support' copies are a second
    draw from the keypoint's support: after undoing the rotation, most of their points are not
    among the patch's, yet all lie on the same surface (the plane z = 0 here), moved only by the
    requested jitter."""
    from sphere_jax.data.readers import io
    rng = np.random.default_rng(0)
    pts = np.c_[rng.uniform(0, 1.5, (6000, 2)), np.zeros(6000)].astype(np.float32)
    io.write_ply(str(tmp_path / "plane.ply"), pts)
    src = patch_source.PatchSource([str(tmp_path / "plane.ply")], voxel=0.01, keypoint_leaf=0.2,
                               radius=0.3, n_points=64, min_points=50)

    def unrotated(draw, jitter=0.0):
        b = src.batch(3, 8, copies=True, occlusion=False, copy_draw=draw, copy_jitter=jitter)
        back = np.einsum("bji,bnj->bni", b["rotations"], b["copies"])   # Rᵀ per copy
        close = lambda k: np.isclose(back[k][:, None], b["patches"][k][None], atol=1e-5)
        shared = np.mean([close(k).all(-1).any(1) for k in range(8)])
        return back, shared

    back, shared = unrotated("patch")
    assert shared > 0.99 and np.abs(back[..., 2]).max() < 1e-5
    back, shared = unrotated("support")
    assert shared < 0.6 and np.abs(back[..., 2]).max() < 1e-5
    back, _ = unrotated("support", jitter=0.01)
    assert 0.007 < back[..., 2].std() < 0.013
    with pytest.raises(ValueError, match="copy_draw"):
        src.batch(0, 2, copies=True, copy_draw="mesh")
    with pytest.raises(ValueError, match="copy_jitter"):
        src.batch(0, 2, copies=True, copy_jitter=-1.0)


def test_scene_poses_chain_the_ground_truth(tmp_path):
    """Poses from a gt.log whose pairs form a chain 0-1, 1-2 (no 0-2 pair): fragment 2 is
    reached through 1, so p_0 = P_2 p_2 with P_2 = T_01 T_12; a scan outside any scene gets -1."""
    from sphere_jax.data import poses
    from sphere_jax.data.readers import io, threedmatch
    from sphere_jax.spherical import so3
    scene = tmp_path / "room"
    scene.mkdir()
    for k in range(3):
        io.write_ply(str(scene / f"cloud_bin_{k}.ply"), np.zeros((4, 3), np.float32))
    io.write_ply(str(tmp_path / "loose.ply"), np.zeros((4, 3), np.float32))
    t01, t12 = np.eye(4), np.eye(4)
    t01[:3, :3], t01[:3, 3] = so3.euler_to_matrix_np(0.3, 0.5, 0.7), [1, 0, 0]
    t12[:3, :3], t12[:3, 3] = so3.euler_to_matrix_np(-0.2, 1.1, 0.4), [0, 2, 0]
    threedmatch.write_gt_log(str(scene / "gt.log"), {(0, 1): t01, (1, 2): t12}, 3)
    paths_ = [str(scene / f"cloud_bin_{k}.ply") for k in (2, 0, 1)] + [str(tmp_path / "loose.ply")]
    ids, pose = poses.scene_poses(paths_)
    assert ids.tolist() == [0, 0, 0, -1] and np.isnan(pose[3]).all()
    np.testing.assert_allclose(pose[1], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(pose[2], t01, atol=1e-12)
    np.testing.assert_allclose(pose[0], t01 @ t12, atol=1e-12)


def test_scan_copies_are_the_same_surface_seen_by_another_scan():
    """copy_draw='scan' on the embedded rooms (ground-truth poses): almost no copy shares a
    point with its patch (it comes from another fragment), yet turned back by the batch's
    rotation it lies on the patch's surface as closely as a second draw from the same scan
    does (mean distance to the patch's nearest point, in units of the radius)."""
    from sklearn.neighbors import KDTree
    src = patch_source.PatchSource(scan_roots.scan_paths("embedded"), 0.02, 0.1, 0.3, 256, 300)

    def gap_and_shared(draw):
        b = src.batch(0, 16, copies=True, occlusion=False, copy_draw=draw)
        back = np.einsum("bji,bnj->bni", b["rotations"], b["copies"])
        gap = np.median([KDTree(p).query(q, k=1)[0].mean() for p, q in zip(b["patches"], back)])
        shared = np.mean([np.isclose(q[:, None], p[None], atol=1e-5).all(-1).any(1).mean()
                          for p, q in zip(b["patches"], back)])
        return gap, shared

    support_gap, support_shared = gap_and_shared("support")
    scan_gap, scan_shared = gap_and_shared("scan")
    print(f"support: gap {support_gap:.3f}, shared {support_shared:.2f}; "
          f"scan: gap {scan_gap:.3f}, shared {scan_shared:.2f}")
    assert support_shared > 0.2 and scan_shared < 0.05
    assert scan_gap < 1.5 * support_gap and scan_gap < 0.1
