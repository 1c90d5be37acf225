import hashlib
import json
import os
import shutil

import numpy as np
import pytest
from sklearn.neighbors import NearestNeighbors

from sphere_jax.data.generators import camera, synthetic
from sphere_jax.data.readers import io
from sphere_jax.data.readers import rgbd, threedmatch

SMALL_CAMERA = camera.Camera(width=160, height=120, fx=146.25, fy=146.25)
SMALL = dict(scene_kwargs=dict(n_frames=16, frames_per_fragment=4, stride=2, voxel=0.04,
                               camera=SMALL_CAMERA),
             shape_kwargs=dict(per_class=2, n_points=500),
             object_kwargs=dict(n_scenes=1, views_per_scene=2, camera=SMALL_CAMERA))


@pytest.fixture(scope="module")
def small_data(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth")
    synthetic.make_all(str(out / "a"), seed=3, n_scenes=1, **SMALL)
    return out


def _digest(root):
    h = {}
    for dirpath, _, files in os.walk(root):
        for name in files:
            path = os.path.join(dirpath, name)
            with open(path, "rb") as f:
                h[os.path.relpath(path, root)] = hashlib.sha256(f.read()).hexdigest()
    return h


def test_same_seed_same_bytes(small_data):
    synthetic.make_all(str(small_data / "b"), seed=3, n_scenes=1, **SMALL)
    a, b = _digest(small_data / "a"), _digest(small_data / "b")
    assert len(a) > 30 and a == b


# The fingerprints of SMALL's data at seed 3: the generator is a pure function of the seed, on
# any machine (the main job's table is then the same wherever it runs).
PINNED = {"3dmatch": "ce35d2c1a385ea15e7a160b466fc28dda7b484e2599ca93d67dce2558c953186",
          "modelnet": "1fa8f6189f3675f484566afe4e78f6a5fb99d62fdbd8449031f8eceae2edc4d8",
          "objects": "699cb222c3a80217880eff325e4b7e04b1d784b4269d957cd43ecef81212cc86"}


def test_the_generated_data_is_the_same_on_every_machine(small_data):
    import open3d
    with open(small_data / "a" / "summary.json") as f:
        prints = json.load(f)["fingerprints"]
    differ = sorted(k for k in PINNED if prints[k] != PINNED[k])
    assert not differ, (f"the {differ} data of seed 3 differ from the pinned bytes (numpy "
                        f"{np.__version__}, open3d {open3d.__version__})")


def test_summary_fingerprints_the_generated_files(small_data, tmp_path):
    with open(small_data / "a" / "summary.json") as f:
        prints = json.load(f)["fingerprints"]
    assert sorted(prints) == ["3dmatch", "modelnet", "objects"]
    assert len(set(prints.values())) == 3
    assert prints["objects"] == synthetic.fingerprint(str(small_data / "a" / "objects"))
    # one byte of one file changes its folder's fingerprint
    copy = tmp_path / "objects"
    shutil.copytree(small_data / "a" / "objects", copy)
    victim = sorted(p for p in copy.iterdir() if p.suffix == ".json")[0]
    victim.write_bytes(victim.read_bytes() + b" ")
    assert synthetic.fingerprint(str(copy)) != prints["objects"]


def test_every_pair_aligns_under_its_ground_truth(small_data):
    root = small_data / "a" / "3dmatch"
    scene = threedmatch.load_fragment_scene(root / "synth-room-0")
    lo = threedmatch.load_fragment_scene(root / "synth-room-0",
                                      root / "3DLoMatch" / "synth-room-0-evaluation")
    assert len(scene.pairs) >= 5
    gains = []
    for s, floor in ((scene, 0.3), (lo, 0.1)):
        for i, j in s.pairs:
            a, b = s.cloud(i).points, s.cloud(j).points
            t = s.transforms[(i, j)]
            nn = NearestNeighbors(n_neighbors=1).fit(a)
            aligned = np.mean(nn.kneighbors(b @ t[:3, :3].T + t[:3, 3])[0] < 0.12)
            assert aligned > floor - 0.05, (i, j, aligned)       # overlap is estimated
            assert abs(aligned - s.overlaps[(i, j)]) < 0.1
            gains.append(aligned - np.mean(nn.kneighbors(b)[0] < 0.12))
    assert np.mean(gains) > 0.2


def test_fragment_poses_and_information_matrices(small_data):
    scene = threedmatch.load_fragment_scene(small_data / "a" / "3dmatch" / "synth-room-0")
    i, j = scene.pairs[0]
    pose = lambda k: threedmatch.read_fragment_info(
        scene.fragment_path(k).replace(".ply", ".info.txt"))[-1]
    np.testing.assert_allclose(np.linalg.inv(pose(i)) @ pose(j), scene.transforms[(i, j)],
                               atol=1e-6)
    info = scene.info[(i, j)]
    assert np.allclose(info, info.T) and np.all(np.linalg.eigvalsh(info) > 0)


def test_shapes_and_object_frames(small_data):
    root = small_data / "a"
    names = (root / "modelnet" / "shape_names.txt").read_text().split()
    assert len(names) >= 10
    shape = io.read_modelnet_txt(root / "modelnet" / names[0] / f"{names[0]}_0001.txt")
    assert shape.points.shape == (500, 3)
    assert np.linalg.norm(shape.points, axis=1).max() <= 1.0 + 1e-5
    frames = root / "objects"
    labels = json.loads((frames / "frame-000000.labels.json").read_text())["instances"]
    assert labels and all(set(x) == {"id", "category", "box", "pose"} for x in labels)
    k = rgbd.read_intrinsics(frames / "camera-intrinsics.txt")
    cloud = rgbd.read_rgbd_frame(frames / "frame-000000.color.png",
                                     frames / "frame-000000.depth.png", k,
                                     rgbd.read_pose(frames / "frame-000000.pose.txt"))
    assert np.percentile(cloud.points[:, 2], 5) > -0.2              # above the floor
    import open3d as o3d
    mask = np.asarray(o3d.io.read_image(str(frames / "frame-000000.mask.png")))
    for x in labels:
        v, u = np.nonzero(mask == x["id"])
        assert [u.min(), v.min(), u.max(), v.max()] == x["box"]


def test_fragments_have_thin_surfaces_at_the_voxel_density():
    """Fused fragments look like 3DMatch's TSDF fragments: one surface with mm noise (the raw
    union of the views had two layers 5 cm apart near walls, a 25 mm median residual) and
    about a plane's worth of points per neighbourhood at the voxel size."""
    from sklearn.neighbors import KDTree
    root = synthetic.ensure_default_data()
    pts = io.read_points(os.path.join(root, "3dmatch", "synth-room-0", "cloud_bin_0.ply")).points
    tree = KDTree(pts)
    centres = pts[np.random.default_rng(0).choice(len(pts), 300, replace=False)]
    residual, counts = [], []
    for idx in tree.query_radius(centres, 0.10):
        q = pts[idx] - pts[idx].mean(0)
        residual.append(np.sqrt(max(np.linalg.eigvalsh(q.T @ q / len(q))[0], 0.0)))
        counts.append(len(idx))
    plane = np.pi * 0.10 ** 2 / 0.025 ** 2                 # points of a flat 10 cm disc
    print(f"median residual {1000 * np.median(residual):.1f} mm, "
          f"{np.median(counts) / plane:.2f}x a plane's points")
    assert np.median(residual) < 0.005
    assert 0.8 < np.median(counts) / plane < 2.2     # v1: 3.3x; redkitchen: 1.4x


def test_a_second_process_generating_the_default_data_keeps_the_first_copy(tmp_path,
                                                                            monkeypatch):
    """Two runs started on an empty cache both generate; the one finishing second must not
    fail on the folder the other moved into place (``os.replace`` refuses a non-empty one)."""
    out = tmp_path / "synthetic"

    def make_all_while_another_finishes(tmp, seed):
        for folder, text in ((tmp, "ours"), (str(out), "theirs")):
            os.makedirs(folder)
            with open(os.path.join(folder, "summary.json"), "w") as f:
                f.write(text)

    monkeypatch.setattr(synthetic, "make_all", make_all_while_another_finishes)
    assert synthetic.ensure_default_data(out_dir=str(out)) == str(out)
    assert (out / "summary.json").read_text() == "theirs"
    assert os.listdir(tmp_path) == ["synthetic"]                 # our copy is gone


def test_default_root_owns_every_kind_of_default_data():
    for kind in ("3dmatch", "modelnet", "objects"):
        root = synthetic.default_root(kind)
        assert os.path.isdir(root) and os.path.basename(root) == kind
    with pytest.raises(ValueError, match="kind must be one of 3dmatch"):
        synthetic.default_root("kitti")
