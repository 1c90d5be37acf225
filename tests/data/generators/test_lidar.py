"""The spinning-LiDAR resampler: rings at the beam elevations, returns on the surface, the
nearest surface along a ray, seeded range noise, and a scene written in the 3DMatch layout."""
import json
import os

import numpy as np
import pytest

from sphere_jax.checks import InputError
from sphere_jax.data.generators import lidar
from sphere_jax.data.readers import io

UP = (0.0, 0.0, 1.0)


def wall(x, half=3.0, step=0.004):
    """A dense plane ``X = x`` facing a sensor at the origin (``[N, 3]``)."""
    y, z = np.meshgrid(np.arange(-half, half, step), np.arange(-1.5, 1.5, step))
    return np.stack([np.full(y.size, x), y.ravel(), z.ravel()], 1)


def elevations_deg(points):
    return np.rad2deg(np.arcsin(points[:, 2] / np.linalg.norm(points, axis=1)))


def test_returns_lie_on_the_rings_and_the_surface():
    sensor = lidar.Lidar(beams=16, elevation=(-15.0, 15.0))
    out = lidar.scan(wall(2.0), sensor, up=UP)
    rings = np.unique(np.round(elevations_deg(out), 4))
    np.testing.assert_allclose(rings, np.linspace(-15, 15, 16), atol=1e-3)
    # The nearest point within the 0.3° footprint is short of the ray's hit by at most
    # range · footprint · tan(incidence) (plus the wall's 4 mm grid).
    r = np.linalg.norm(out, axis=1)
    incidence = np.arccos(np.clip(out[:, 0] / r, -1, 1))
    bound = r * np.deg2rad(0.3) * np.tan(incidence) + 2e-3
    assert np.all(np.abs(out[:, 0] - 2.0) <= bound)
    assert np.abs(out[:, 0] - 2.0).max() > 5e-3      # the bound is not vacuous
    # One return per azimuth step across the wall's ±56°.
    per_ring = len(out) / 16
    assert abs(per_ring - 2 * np.rad2deg(np.arctan(3.0 / 2.0)) / 0.2) < 4


def test_the_nearest_surface_occludes_what_is_behind():
    near = wall(1.0, half=0.3)                      # a panel in front of the far wall
    out = lidar.scan(np.concatenate([wall(3.0), near]), lidar.Lidar(beams=8), up=UP)
    azimuth = np.rad2deg(np.arctan2(out[:, 1], out[:, 0]))
    elevation = elevations_deg(out)
    inside = (np.abs(azimuth) < 14) & (np.abs(elevation) < 20)    # well inside the panel
    assert inside.sum() > 100
    assert np.abs(out[inside, 0] - 1.0).max() < 4e-3
    outside = np.abs(azimuth) > 20
    assert np.abs(out[outside, 0] - 3.0).max() < 0.06       # oblique: the footprint


def test_range_noise_is_seeded_and_has_its_sigma():
    sensor = lidar.Lidar(beams=16, elevation=(-15.0, 15.0), range_noise=0.01)
    a = lidar.scan(wall(2.0), sensor, up=UP, rng=np.random.default_rng(3))
    b = lidar.scan(wall(2.0), sensor, up=UP, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    exact = lidar.scan(wall(2.0), sensor, up=UP)
    ratio = np.linalg.norm(a, axis=1) / np.linalg.norm(exact, axis=1)
    sigma = np.std((ratio - 1) * np.linalg.norm(exact, axis=1))
    assert 0.009 < sigma < 0.011


def test_bad_up_is_refused():
    with pytest.raises(InputError, match="forward"):
        lidar.sensor_frame(up=(0.0, 0.0, 1.0), forward=(0.0, 0.0, 2.0))
    with pytest.raises(InputError, match="up"):
        lidar.sensor_frame(up=(0.0, 0.0, 0.0))


def test_scan_fragments_writes_a_3dmatch_scene(tmp_path):
    from sphere_jax.data.readers import ply
    scene = tmp_path / "src" / "kitchen"
    scene.mkdir(parents=True)
    rotated = wall(2.0)[:, [1, 2, 0]] * [1, -1, 1]     # camera frame: z forward, y down
    ply.write_ply(scene / "cloud_bin_3.ply", rotated)
    counts = lidar.scan_fragments(scene, tmp_path / "out", seed=1)
    out = io.read_points(str(tmp_path / "out" / "kitchen" / "cloud_bin_3.ply")).points
    assert counts == {3: len(out)} and len(out) > 1000
    assert np.abs(out[:, 2] - 2.0).max() < 0.06               # 1 cm noise, 5 sigma
    meta = json.loads((tmp_path / "out" / "kitchen" / "lidar.json").read_text())
    assert meta["beams"] == 32 and meta["returns"] == {"3": len(out)}
    assert not os.path.exists(tmp_path / "out" / "kitchen" / "gt.log")


@pytest.mark.parametrize("field", [dict(beams=0), dict(azimuth_step=-1.0),
                                   dict(range_noise=-0.1), dict(elevation=(10.0, -10.0))])
def test_bad_sensors_are_refused(field):
    with pytest.raises(InputError, match=next(iter(field))):
        lidar.Lidar(**field)
