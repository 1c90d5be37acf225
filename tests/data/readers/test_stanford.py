"""Stanford .conf poses align the real bunny scans (the conjugate-quaternion convention)."""
import os

import numpy as np
from sklearn.neighbors import NearestNeighbors

from sphere_jax.data.readers import io, stanford


def _transform(points, t):
    return points @ t[:3, :3].T + t[:3, 3]


def test_stanford_bunny_conf_aligns_scans(shared):
    root = os.path.join(shared, "stanford/bunny/data")
    conf = stanford.read_stanford_conf(os.path.join(root, "bun.conf"))
    p0 = io.read_ply(os.path.join(root, "bun000.ply")).points
    p45 = io.read_ply(os.path.join(root, "bun045.ply")).points
    nn = NearestNeighbors(n_neighbors=1).fit(_transform(p0, conf["bun000.ply"]))
    d = nn.kneighbors(_transform(p45, conf["bun045.ply"]))[0][:, 0]
    overlap = d < 0.002
    assert overlap.mean() > 0.5 and d[overlap].mean() < 0.001
    d_raw = NearestNeighbors(n_neighbors=1).fit(p0).kneighbors(p45)[0][:, 0]
    assert np.mean(d_raw < 0.002) < overlap.mean() - 0.2
    scans = stanford.load_stanford_scans(os.path.join(root, "bun.conf"))
    t = scans.transform("bun000.ply", "bun045.ply")                   # 45 -> 0
    d_pair = nn.kneighbors(_transform(_transform(p45, t), conf["bun000.ply"]))[0][:, 0]
    np.testing.assert_allclose(d_pair, d, atol=1e-5)
