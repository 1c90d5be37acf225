"""Expected outputs of the shipped bundles on a fixed synthetic cloud: the fixture that proves a
refactor changed no behaviour (``tests/models/test_shipped.py``).

Regenerate (only when a bundle is deliberately retrained) with
``python -m tests.models.shipped_outputs``; it rewrites ``shipped_outputs.npz`` beside this file.
"""
from __future__ import annotations

import os

import numpy as np

import sphere_jax
from sphere_jax.models import shipped

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURE = os.path.join(HERE, "shipped_outputs.npz")
RADIUS = 0.3


def cloud():
    """``[N, 3]`` points on a bumpy floor, a wall and a box corner (metres), seeded: enough
    structure for an LRF to be defined, small enough to describe in seconds."""
    rng = np.random.default_rng(7)
    u = rng.uniform(-1, 1, (3000, 2))
    floor = np.c_[u, 0.05 * np.sin(4 * u[:, 0]) * np.cos(3 * u[:, 1])]
    v = rng.uniform(-1, 1, (1500, 2))
    wall = np.c_[v[:, 0], np.full(len(v), 1.0), 0.5 * (v[:, 1] + 1)]
    w = rng.uniform(0, 0.3, (900, 2))
    box = np.concatenate([np.c_[w, np.full(300 * 3, 0.3)][:300],
                          np.c_[np.full(300, 0.3), w[300:600]],
                          np.c_[w[600:, 0], np.full(300, 0.3), w[600:, 1]]])
    return np.concatenate([floor, wall, box]).astype(np.float32)


KEYPOINTS = np.array([10, 200, 3001, 3500, 4600, 4800, 5100, 5300])


def bundle(name):
    return shipped.bundle_path(name, required=True)


def compute():
    """Name -> array of every shipped bundle's orient/describe outputs on :func:`cloud`."""
    pts, kp, out = cloud(), KEYPOINTS, {}
    kw = dict(radius=RADIUS, workers=1)
    compass = sphere_jax.load_bundle(bundle("compass"))
    out["compass_orient"] = compass.orient(pts, kp, **kw)
    for name in ("compass_rooms", "lrf_net"):             # the other shipped frames
        out[f"{name}_orient"] = sphere_jax.load_bundle(bundle(name)).orient(pts, kp, **kw)
    lead = sphere_jax.load_bundle(bundle("lead"))
    lead_pn = sphere_jax.load_bundle(bundle("lead_pn"))
    # The networks' own outputs, and those outputs whitened as describe() gives them.
    out["lead_describe"] = lead.describe(pts, kp, whiten=None, **kw)
    out["lead_compass_describe"] = lead.describe(pts, kp, frames=out["compass_orient"], **kw)
    out["lead_pn_describe"] = lead_pn.describe(pts, kp, whiten=None, **kw)
    out["lead_describe_whitened"] = lead.describe(pts, kp, **kw)
    out["lead_compass_describe_whitened"] = lead.describe(
        pts, kp, frames=out["compass_orient"], whiten="compass", **kw)
    out["lead_pn_describe_whitened"] = lead_pn.describe(pts, kp, **kw)
    sound = sphere_jax.load_bundle(bundle("sound"))
    out["sound_orient"] = sound.orient(pts, kp, **kw)
    out["sound_describe"] = sound.describe(pts, kp, whiten=None, **kw)
    out["sound_describe_whitened"] = sound.describe(pts, kp, **kw)
    shapes = sphere_jax.load_bundle(bundle("compass_shapes"))
    unit = pts[:shapes.config.data.n_points * 2].reshape(2, -1, 3)
    unit = (unit - unit.mean(1, keepdims=True)) / 1.5
    out["compass_shapes_orient"] = shapes.orient_patches(unit, workers=1)
    return {k: np.asarray(v, np.float32) for k, v in out.items()}


if __name__ == "__main__":
    got = compute()
    np.savez_compressed(FIXTURE, **got)
    print(f"wrote {FIXTURE}: " + ", ".join(f"{k} {v.shape}" for k, v in got.items()))
