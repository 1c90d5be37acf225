"""Fragments fused from posed RGB-D frames: real Kinect frames (3DMatch toolbox) when present,
else the embedded synthetic table-top frames (same layout)."""
import os

import numpy as np
import pytest
from sklearn.neighbors import KDTree

from sphere_jax.data import fusion, patch_source, scan_roots
from sphere_jax.data.readers import io, rgbd


def test_each_frame_lies_on_its_fused_fragment(frames):
    """A frame's own back-projection, moved by its pose into the run's first camera, lies on
    the fused fragment (median gap under the 1 cm fusion voxel); a wrong pose convention (the
    inverse, or world coordinates) leaves it decimetres away."""
    seq = rgbd.read_frame_sequence(frames)
    run = [0, 1, 2]
    tree = KDTree(fusion.fuse(seq, run))
    a = seq.poses[run[0]]
    for f in run:
        cloud = rgbd.read_rgbd_frame(None, seq.depth[f], seq.intrinsics,
                                     np.linalg.inv(a) @ seq.poses[f],
                                     depth_trunc=fusion.DEPTH_TRUNC).points[::50]
        gap = np.median(tree.query(cloud)[0])
        wrong = rgbd.read_rgbd_frame(None, seq.depth[f], seq.intrinsics, seq.poses[f],
                                     depth_trunc=fusion.DEPTH_TRUNC).points[::50]
        print(f"frame {f}: median gap {100 * gap:.2f} cm; in world coordinates "
              f"{100 * np.median(tree.query(wrong)[0]):.1f} cm")
        assert gap < fusion.FUSION_VOXEL
        if f == 0:
            assert np.median(tree.query(wrong)[0]) > 0.05 or np.allclose(a, np.eye(4), atol=1e-3)


def test_fragments_are_cached_and_found_as_scans(frames, tmp_path, monkeypatch):
    monkeypatch.setenv("SPHERE_JAX_DATA", str(tmp_path))
    seq = rgbd.read_frame_sequence(frames)
    files = scan_roots.find_scans(frames)
    n = len(fusion.fragment_runs(len(seq), 25, 25))
    assert len(files) == n and all(os.path.isfile(f) for f in files)
    stamp = [os.path.getmtime(f) for f in files]
    assert scan_roots.find_scans(frames) == files                 # cached: not fused again
    assert [os.path.getmtime(f) for f in files] == stamp
    assert fusion.fused_source(os.path.dirname(files[0])) == os.path.abspath(frames)


def test_open3d_layout_reads_as_the_same_sequence(frames, tmp_path):
    """The same frames in open3d's layout (``depth/``, ``color/``, ``trajectory.log``, an
    intrinsics JSON in the parent) read as the same sequence and fuse to the same fragment."""
    import json
    import shutil
    from sphere_jax.data.readers import threedmatch
    seq = rgbd.read_frame_sequence(frames)
    run = [0, 1, 2]
    folder = tmp_path / "scene" / "RGBD"
    for sub in ("depth", "color"):
        os.makedirs(folder / sub)
    for f in run:
        shutil.copy(seq.depth[f], folder / "depth" / f"{f:05d}.png")
        shutil.copy(seq.color[f], folder / "color" / f"{f:05d}.png")
    # open3d's trajectory.log: one block per frame, in order (its header is not a pair)
    threedmatch.write_pair_blocks(str(folder / rgbd.TRAJECTORY),
                                  {(f, f): seq.poses[f] for f in run}, len(run))
    with open(tmp_path / "scene" / "camera_sensor.json", "w") as out:
        json.dump({"width": 640, "height": 480,
                   "intrinsic_matrix": seq.intrinsics.T.ravel().tolist()}, out)
    assert rgbd.is_frame_sequence(folder)
    other = rgbd.read_frame_sequence(folder)
    assert len(other) == len(run)
    np.testing.assert_allclose(other.poses, seq.poses[run], atol=1e-9)
    np.testing.assert_allclose(other.intrinsics, seq.intrinsics)
    np.testing.assert_array_equal(fusion.fuse(other, [0, 1, 2]), fusion.fuse(seq, run))
    with open(tmp_path / "scene" / "camera_other.json", "w") as out:      # which one?
        json.dump({"intrinsic_matrix": [1] * 9}, out)
    with pytest.raises(io.DataError, match="2 candidate camera intrinsics"):
        rgbd.read_frame_sequence(folder)
    os.remove(tmp_path / "scene" / "camera_other.json")
    os.remove(folder / "depth" / "00002.png")
    with pytest.raises(io.DataError, match="3 poses for 2 depth images"):
        rgbd.read_frame_sequence(folder)


def test_fragment_runs():
    assert fusion.fragment_runs(50, 25, 25) == [list(range(25)), list(range(25, 50))]
    assert fusion.fragment_runs(63, 25, 25)[-1] == list(range(50, 63))   # ≥ half a run
    assert len(fusion.fragment_runs(55, 25, 25)) == 2                   # 5 frames: dropped
    with pytest.raises(ValueError, match="stride"):
        fusion.fragment_runs(10, 5, 0)


def test_root_weights_draw_each_entry_by_its_share(tmp_path):
    rng = np.random.default_rng(0)
    scans = []
    for k in range(2):                       # two flat 'scans' with very different sizes
        n = 4000 if k == 0 else 1200
        pts = np.c_[rng.uniform(0, 1.5 if k == 0 else 0.7, (n, 2)), np.zeros(n)]
        path = tmp_path / f"scan{k}.ply"
        io.write_ply(str(path), pts.astype(np.float32) + [10.0 * k, 0, 0])
        scans.append(str(path))
    kw = dict(voxel=0.02, keypoint_leaf=0.1, radius=0.3, n_points=32, min_points=50)
    plain = patch_source.PatchSource(scans, **kw)
    counts = np.bincount(plain.splits["train"][:, 0])
    assert counts[0] > 2 * counts[1]                 # by keypoint count: scan 0 dominates
    w = scan_roots.parse_weights("1,1", 2)
    even = patch_source.PatchSource(scans, **kw, groups=[0, 1], weights=w)
    share = np.mean([np.mean(even.draw(np.random.default_rng(s), 64)[:, 0] == 1)
                     for s in range(20)])
    assert 0.4 < share < 0.6
    only = patch_source.PatchSource(scans, **kw, groups=[0, 1],
                                weights=scan_roots.parse_weights("0,3", 2))
    assert np.all(only.draw(np.random.default_rng(0), 64)[:, 0] == 1)
    assert only.batch(0, 4)["patches"].shape == (4, 32, 3)
    with pytest.raises(ValueError, match="root_weights"):
        scan_roots.parse_weights("1,x", 2)
    with pytest.raises(ValueError, match="one per data.root entry"):
        scan_roots.parse_weights("1,1,1", 2)
