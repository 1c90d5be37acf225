"""The inference API: bundles orient and describe in chunks, concurrently, with clear errors
(model equivariance is tested per model in tests/models/)."""
import json
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from configs import lead, sound
import sphere_jax
from sphere_jax import models, parallel, training
from sphere_jax.bundles import inference
from sphere_jax.models import shipped
from tests import reference


@pytest.mark.slow
def test_bundle_api_shapes_chunks_and_errors(tmp_path):
    config = sound.get_config("tiny")
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    variables = reference.init(model, x * 0.3)
    state = {"params": variables["params"], "batch_stats": variables["batch_stats"]}
    training.checkpoints.save_bundle(str(tmp_path), config, state)
    bundle = inference.load_bundle(tmp_path / "bundle")
    cloud = np.random.default_rng(1).uniform(-1, 1, (3000, 3)).astype(np.float32)
    kp = np.arange(7)
    d1 = bundle.describe(cloud, kp, radius=0.5, chunk=3, workers=1)
    d2 = bundle.describe(cloud, kp, radius=0.5, chunk=256)
    assert d1.shape == (7, 512) and np.allclose(d1, d2, atol=1e-5)
    # Concurrent chunks: same rows, same order, bit for bit (the last chunk is padded).
    assert np.array_equal(bundle.describe(cloud, kp, radius=0.5, chunk=3, workers=3), d1)
    assert bundle.orient(cloud, cloud[:5], radius=0.5).shape == (5, 3, 3)   # by coordinates
    with pytest.raises(ValueError, match="at least 16 points; got 1 of 1"):
        bundle.orient(np.concatenate([cloud, [[9.0, 9.0, 9.0]]]), [3000], radius=0.5)
    with pytest.raises(sphere_jax.SphereJaxError, match="not a bundle"):
        inference.load_bundle(tmp_path)
    with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be a bundle folder or one"):
        inference.load_bundle(None)
    for name in shipped.SHIPPED:                  # shipped bundles by name: the same folder
        assert inference.bundle_path(name) == shipped.bundle_path(name, required=True)
        kind = inference.load_bundle(name).kind
        assert kind == shipped.SHIPPED[name].kind
    lead_config = lead.get_config("tiny")
    with pytest.raises(ValueError, match="of kind compass, sound, lrf_net to orient"):
        inference.Bundle(models.build(lead_config), {}, lead_config).orient(cloud, kp)


def test_run_chunked_order_padding_and_workers():
    calls = []

    def fn(x):
        calls.append(len(x))
        return x * 2

    x = np.arange(10, dtype=np.float32)[:, None]
    for workers in (1, 2, 4):
        calls.clear()
        out = parallel.run_chunked(fn, x, 4, workers)
        assert np.array_equal(out, x * 2) and calls == [4, 4, 4]     # padded to one shape
    assert parallel.run_chunked(fn, x[:0], 4).shape == (0,)
    assert parallel.default_workers() >= 1
    with pytest.raises(ValueError, match="workers must be a positive integer; got 0"):
        parallel.run_chunked(fn, x, 4, workers=0)
    with pytest.raises(ValueError, match="chunk must be a positive integer; got 0"):
        parallel.run_chunked(fn, x, 0)


def test_in_slices_equals_the_whole_call(monkeypatch):
    """Slices of 4 rows inside one traced call: the same rows, a pytree and a None argument
    carried through, and the whole call where the rows do not split into slices or the call
    runs on an accelerator or several devices."""
    seen = []

    def fn(x, frames=None):
        seen.append(x.shape[0])
        rows = jnp.tanh(x @ jnp.ones((3, 2)))
        return {"rows": rows, "sum": x.sum(1) + (0 if frames is None else frames.sum((1, 2)))}

    x = jnp.asarray(np.random.default_rng(0).normal(size=(12, 3)), jnp.float32)
    frames = jnp.ones((12, 3, 3))
    for args in ((x,), (x, None), (x, frames)):
        seen.clear()
        got, want = jax.jit(parallel.in_slices(fn, 4))(*args), fn(*args)
        assert seen[0] == 4
        for key in want:
            np.testing.assert_allclose(got[key], want[key], rtol=1e-6)
    for size, k in ((None, 12), (5, 12), (12, 12), (16, 12)):
        seen.clear()
        jax.jit(parallel.in_slices(fn, size))(x[:k])
        assert seen == [k]
    for name, value in (("default_backend", lambda: "gpu"), ("local_device_count", lambda: 2)):
        with monkeypatch.context() as m:
            m.setattr(jax, name, value)
            seen.clear()
            jax.jit(parallel.in_slices(fn, 4))(x)
            assert seen == [12], name


@pytest.fixture(scope="module")
def sound_bundle(tmp_path_factory):
    """A tiny untrained SOUND bundle on disk: it orients and describes (and takes no frames)."""
    root = tmp_path_factory.mktemp("sound_bundle")
    config = sound.get_config("tiny")
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    variables = reference.init(model, x * 0.3)
    training.checkpoints.save_bundle(str(root), config, {"params": variables["params"],
                                             "batch_stats": variables["batch_stats"]})
    return root / "bundle"


CLOUD = np.random.default_rng(1).uniform(-1, 1, (3000, 3)).astype(np.float32)


@pytest.mark.parametrize("kwargs, message", [
    (dict(keypoints=np.zeros(3000, bool)), "boolean mask"),
    (dict(keypoints=np.array([1.0, 2.0])), r"integer indices \[K\] into points or float "
                                           r"coordinates \[K, 3\]"),
    (dict(keypoints=CLOUD[0]), r"shape \(3,\)"),
    (dict(keypoints=CLOUD[:4, :2]), r"shape \(4, 2\)"),
    (dict(radius=0), "radius must be a positive finite number; got 0"),
    (dict(radius=-1.0), "got -1.0"),
    (dict(chunk=2.5), "chunk must be a positive integer; got 2.5"),
    (dict(workers=0), "workers must be a positive integer; got 0"),
    (dict(points=np.zeros((0, 3))), "points must be a non-empty cloud"),
    (dict(points=np.array([[np.nan, 0, 0]] + [[0, 0, 0]] * 9)), "non-finite point"),
    (dict(points=np.zeros(30)), r"points must be a float array \[N, 3\]"),
    (dict(on_invalid="skip"), "on_invalid must be one of 'raise', 'mask'; got 'skip'"),
    (dict(seed=-1), "seed must be a non-negative integer; got -1"),
])
def test_api_refuses_bad_arguments_before_any_work(sound_bundle, kwargs, message):
    args = dict(points=CLOUD, keypoints=np.arange(4))
    args.update(kwargs)
    for call in (sphere_jax.orient, sphere_jax.describe):
        with pytest.raises(sphere_jax.SphereJaxError, match=message):
            call(str(sound_bundle), **args)


def test_several_clouds_are_a_list_of_pairs_with_one_result_each(sound_bundle):
    bundle = inference.load_bundle(sound_bundle)
    for bad in (CLOUD, [], [CLOUD], [(CLOUD, np.arange(4), None)]):
        with pytest.raises(sphere_jax.SphereJaxError, match="clouds must be a non-empty list"):
            bundle.orient_clouds(bad)
    with pytest.raises(sphere_jax.SphereJaxError, match="frames must be a list of one"):
        inference.load_bundle("lead").describe_clouds([(CLOUD, np.arange(4))], frames=np.eye(3))
    two = bundle.orient_clouds([(CLOUD, np.arange(4)), (CLOUD[::2], np.arange(3))])
    assert [f.shape for f in two] == [(4, 3, 3), (3, 3, 3)]


def test_describing_draws_supports_evenly_unless_asked_to_draw_as_training(sound_bundle):
    """The default draw is 'even'; draw='random' (what the whitening is fitted on) gives the
    supports training draws, and another word is refused by name."""
    bundle = inference.load_bundle(sound_bundle)
    kp = np.arange(6)
    even = bundle.describe_clouds([(CLOUD, kp)], radius=0.3)[0]
    np.testing.assert_array_equal(even, bundle.describe_clouds([(CLOUD, kp)], radius=0.3,
                                                               draw="even")[0])
    random = bundle.describe_clouds([(CLOUD, kp)], radius=0.3, draw="random")[0]
    assert np.abs(random - even).max() > 1e-3
    with pytest.raises(sphere_jax.SphereJaxError, match="draw must be one of"):
        bundle.describe_clouds([(CLOUD, kp)], radius=0.3, draw="grid")


def test_too_small_supports_are_reported_never_described(sound_bundle):
    bundle = inference.load_bundle(sound_bundle)
    lonely = np.concatenate([CLOUD, [[5, 5, 5], [5.01, 5, 5]]]).astype(np.float32)
    kp = np.array([0, 3000, 1])                 # 3000 has one neighbour: 1024 copies of it
    with pytest.raises(sphere_jax.SphereJaxError, match=r"1 of 3 with fewer \(the first, "
                                                        r"keypoint 1, has 1\)"):
        bundle.orient(lonely, kp, radius=0.3)
    frames, valid = bundle.orient(lonely, kp, radius=0.3, on_invalid="mask")
    assert valid.tolist() == [True, False, True] and np.isnan(frames[1]).all()
    ok = bundle.orient(lonely, kp[valid], radius=0.3)
    np.testing.assert_allclose(frames[valid], ok, atol=1e-6)     # the same stream of patches
    desc, valid = bundle.describe(lonely, kp[1:2], radius=0.3, on_invalid="mask")
    assert desc.shape == (1, 512) and not valid[0]               # the width even when none is


def test_frames_must_be_rotations_and_only_where_used(sound_bundle):
    from configs import lead as lead_config
    config = lead_config.get_config("tiny")
    model = models.build(config)
    x = np.zeros((1, config.data.n_points, 3), np.float32)
    lead = inference.Bundle(model, reference.init(model, x), config)
    for frames, message in [(np.zeros((4, 3, 3)), "not.*det = 0"),
                            (np.full((4, 3, 3), np.nan), "non-finite"),
                            (np.eye(3), r"rotations \[4, 3, 3\]")]:
        with pytest.raises(sphere_jax.SphereJaxError, match="frames must be " if
                           frames.ndim == 2 else message):
            lead.describe(CLOUD, np.arange(4), radius=0.3, frames=frames)
    with pytest.raises(sphere_jax.SphereJaxError, match="frames must be None for a sound"):
        inference.load_bundle(sound_bundle).describe(CLOUD, np.arange(4), frames=np.eye(3)[None])


def _untrained(config_module, **data):
    config = config_module.get_config("tiny")
    config.data.update(data)
    model = models.build(config)
    x = np.random.default_rng(0).normal(size=(2, config.data.n_points, 3)).astype(np.float32)
    return inference.Bundle(model, reference.init(model, x * 0.3), config)


def test_an_orienting_bundle_as_frames_gives_the_values_of_its_frames(sound_bundle):
    """LEAD with a Compass bundle as ``frames`` runs both on one draw of patches, in one call
    per chunk: the same descriptors as Compass's frames passed as arrays, bit for bit."""
    from configs import compass as compass_config
    lead_bundle, compass = _untrained(lead), _untrained(compass_config)
    lonely = np.concatenate([CLOUD, [[5, 5, 5]]]).astype(np.float32)
    clouds = [(lonely, np.array([0, 3000, 7])), (CLOUD, np.arange(10, 15))]
    frames = [np.where(v[:, None, None], f, np.eye(3)) for f, v in
              compass.orient_clouds(clouds, radius=0.3, on_invalid="mask")]
    apart = lead_bundle.describe_clouds(clouds, radius=0.3, frames=frames, on_invalid="mask")
    joint = lead_bundle.describe_clouds(clouds, radius=0.3, frames=compass, on_invalid="mask")
    for (a, va), (b, vb) in zip(apart, joint):
        np.testing.assert_array_equal(va, vb)
        np.testing.assert_array_equal(a, b)
    assert not joint[0][1][1] and np.isnan(joint[0][0][1]).all()   # no support: no frame
    one = lead_bundle.describe(CLOUD, np.arange(10, 15), radius=0.3, frames=compass)
    np.testing.assert_array_equal(one, joint[1][0])
    wide = _untrained(compass_config, n_points=32)
    with pytest.raises(sphere_jax.SphereJaxError, match="frames must be an orienting bundle "
                                                        "whose patches.*32 points"):
        lead_bundle.describe(CLOUD, np.arange(4), radius=0.3, frames=wide)
    with pytest.raises(sphere_jax.SphereJaxError, match="frames must be None for a sound"):
        inference.load_bundle(sound_bundle).describe(CLOUD, np.arange(4), frames=compass)
    with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be of kind"):
        lead_bundle.describe(CLOUD, np.arange(4), radius=0.3, frames=lead_bundle)


def test_coordinate_keypoints_are_queried_not_added(sound_bundle):
    bundle = inference.load_bundle(sound_bundle)
    far = np.array([[3.0, 3.0, 3.0], [3.01, 3.0, 3.0]], np.float32)
    cloud = np.concatenate([CLOUD, far[:1] + [0.0, 0.05, 0.0]] * 1).astype(np.float32)
    # Neither coordinate is a support point of the other: each sees the one cloud point only.
    stream = bundle.supports(cloud, far, radius=0.3)
    assert stream.counts.tolist() == [1, 1]
    p = bundle.patches(np.concatenate([cloud] + [cloud[-1:]] * 20), far, radius=0.3)
    np.testing.assert_allclose(p[0], np.broadcast_to([0.0, 0.05 / 0.3, 0.0], p[0].shape),
                               atol=1e-6)


def test_corrupt_or_mismatched_bundles_name_the_bundle(sound_bundle, tmp_path):
    import shutil
    bad = tmp_path / "bundle"
    shutil.copytree(sound_bundle, bad)
    config = bad / "config.json"
    text = config.read_text()
    edited = json.loads(text)
    edited["model_kwargs"]["s2_features"] += 1
    config.write_text(json.dumps(edited))
    mismatch = r"shape .*\(config and weights do not match\)"
    with pytest.raises(sphere_jax.SphereJaxError, match=rf"bundle {bad}: parameter .* has "
                                                        + mismatch):
        inference.load_bundle(bad)
    config.write_text(text[:50])
    with pytest.raises(sphere_jax.SphereJaxError, match="config.json is unreadable"):
        inference.load_bundle(bad)

def test_truncated_weights_name_the_bundle_and_leave_no_stray_reports(tmp_path, caplog,
                                                                      unraisable_reports):
    """A shipped-size bundle: its many shards leave reads in flight when one fails."""
    import gc
    import shutil
    bad = tmp_path / "bundle"
    shutil.copytree(shipped.bundle_path("sound", required=True), bad)
    data = max((p for p in (bad / "variables").rglob("*") if p.is_file()),
               key=lambda p: p.stat().st_size)
    data.write_bytes(data.read_bytes()[:64])
    for _ in range(3):        # the reads left behind differ from one try to the next
        with pytest.raises(sphere_jax.SphereJaxError, match=rf"bundle {bad}: the weights in "
                                                            r"variables/ cannot be restored"):
            inference.load_bundle(bad)
    gc.collect()
    assert unraisable_reports == []         # orbax's abandoned reads were collected, quietly
    assert [r.getMessage()[:80] for r in caplog.records if r.name == "asyncio"] == []


def test_support_memory_does_not_grow_with_the_keypoints(sound_bundle):
    """Peak Python allocations (numpy's buffers) of orienting K keypoints: chunks stream, so
    8× the keypoints may not cost much more than the output itself."""
    import tracemalloc
    bundle = inference.load_bundle(sound_bundle)
    dense = np.random.default_rng(2).uniform(-1, 1, (60_000, 3)).astype(np.float32)
    bundle.orient(dense, np.arange(8), radius=0.3, chunk=64, workers=1)      # compile
    peaks = {}
    for k in (256, 2048):
        tracemalloc.start()
        bundle.orient(dense, np.arange(k), radius=0.3, chunk=64, workers=1)
        peaks[k] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    # Materialised, 2048 supports of ~680 neighbours and their patches took ~8× the 256's.
    assert peaks[2048] < 2.0 * peaks[256], peaks


@pytest.mark.slow
def test_open3d_clouds_in_and_features_out_for_open3d_ransac():
    """open3d users pass their clouds and hand our descriptors to open3d's own RANSAC."""
    import open3d as o3d
    from sphere_jax.data import demo, patches
    from sphere_jax.eval import registration
    (src, dst), t_gt = demo.fragment_pair()
    reg = o3d.pipelines.registration
    clouds, features = [], []
    for k, pts in enumerate((src, dst)):
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts.astype(np.float64)))
        kp = patches.random_keypoints(pts, 1500, np.random.default_rng(k))
        # Keypoints whose support is too thin to describe (stray points) are left out.
        _, valid = sphere_jax.describe("lead_pn", pcd, kp, on_invalid="mask")
        kp = kp[valid]
        feature = sphere_jax.describe("lead_pn", pcd, kp, as_open3d=True)
        assert feature.dimension() == 512 and feature.num() == len(kp)
        with pytest.raises(sphere_jax.SphereJaxError, match="as_open3d must be True or False"):
            sphere_jax.describe("lead_pn", pcd, kp[:2], as_open3d="yes")
        if k == 0:                         # the same numbers from numpy and a tensor cloud
            tensor = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts.astype(np.float32)))
            np.testing.assert_allclose(sphere_jax.describe("lead_pn", tensor, kp),
                                       feature.data.T, atol=1e-5)
        clouds.append(pcd.select_by_index(kp.tolist()))
        features.append(feature)
    o3d.utility.random.seed(0)
    out = reg.registration_ransac_based_on_feature_matching(
        clouds[0], clouds[1], features[0], features[1], True, 0.05,
        reg.TransformationEstimationPointToPoint(False), 3,
        [reg.CorrespondenceCheckerBasedOnDistance(0.05)],
        reg.RANSACConvergenceCriteria(100_000, 0.999))
    rre, rte = registration.rre_rte(np.asarray(out.transformation), t_gt)
    assert rre < 10 and rte < 0.3, (rre, rte)


SHARDED_CHILD = """
import sys, numpy as np, jax
from sphere_jax import parallel
from sphere_jax.bundles import inference
from sphere_jax.data import demo, patches
assert parallel.chunk_sharding().mesh.size == jax.local_device_count() == 2
(src, _), _ = demo.fragment_pair()
kp = patches.random_keypoints(src, 150, np.random.default_rng(0))
np.savez(sys.argv[1], compass=inference.load_bundle('compass').orient(src, kp, chunk=25),
         lead=inference.load_bundle('lead').describe(src, kp, chunk=25))
"""


@pytest.mark.slow
def test_chunks_split_over_two_host_devices_give_the_same_results(tmp_path):
    """With two local devices every chunk is one SPMD program over both (a sharded batch
    axis); frames and descriptors equal those of one device."""
    import subprocess
    import sys
    from sphere_jax.data import demo, patches
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    out = tmp_path / "two.npz"
    run = subprocess.run([sys.executable, "-c", SHARDED_CHILD, str(out)], env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    two = np.load(out)
    assert parallel.chunk_sharding() is None                       # this process: one device
    (src, _), _ = demo.fragment_pair()
    kp = patches.random_keypoints(src, 150, np.random.default_rng(0))
    np.testing.assert_allclose(two["compass"], inference.load_bundle("compass").orient(src, kp),
                               atol=1e-5)
    np.testing.assert_allclose(two["lead"], inference.load_bundle("lead").describe(src, kp),
                               atol=1e-5)


def test_frame_hypotheses_are_refused_by_a_bundle_without_them_and_for_a_bad_count():
    pts = np.random.default_rng(0).normal(size=(500, 3)).astype(np.float32) * 0.1
    with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be of kind compass"):
        inference.load_bundle("lead").orient_modes(pts, np.arange(3), 2, radius=0.3)
    with pytest.raises(sphere_jax.SphereJaxError, match="k must be a positive"):
        inference.load_bundle("compass").orient_modes(pts, np.arange(3), 0, radius=0.3)
