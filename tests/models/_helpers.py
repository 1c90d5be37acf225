"""Inputs and measures shared by the model tests."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax.spherical import so3, transforms
from tests import reference


def surfaces(n=6, points=2000, seed=0):
    """``[n, points, 3]`` unit-ball patches of ``n`` different smooth surfaces (float32)."""
    rng = np.random.default_rng(seed)
    uv = rng.uniform(-0.7, 0.7, (n, points, 2))
    a, b, c = (rng.normal(size=(n, 1, 1)) for _ in range(3))
    z = (0.3 * np.sin(3 * a * uv[..., :1]) + 0.3 * b * uv[..., 1:] ** 2
         + 0.2 * c * uv[..., :1] * uv[..., 1:])
    return np.concatenate([uv, z], -1).astype(np.float32)


def map_equivariance(maps_fn, patches, seeds=(0, 1, 2)):
    """``maps(R·P)`` against ``L_R maps(P)`` for SO(3) maps ``[N, 2b, 2b, 2b]``: relative errors
    per rotation, and the same comparison against the other patches' maps, for scale."""
    base = maps_fn(patches)
    rotate = jax.jit(jax.vmap(transforms.rotate_so3, (0, None)))
    errs, unrelated = [], []
    for seed in seeds:
        rot = np.asarray(so3.random_rotation(jax.random.PRNGKey(seed)))
        lhs = maps_fn(patches @ rot.T)
        rhs = rotate(base, rot)
        norm = jnp.linalg.norm(rhs)
        errs.append(float(jnp.linalg.norm(lhs - rhs) / norm))
        unrelated.append(float(jnp.linalg.norm(lhs - jnp.roll(rhs, 1, 0)) / norm))
    return np.array(errs), np.array(unrelated)


def assert_maps_equivariant(label, model, maps, capsys, tol=0.25):
    """Initialise ``model`` on :func:`surfaces` and check that ``maps(model, variables, x)``
    (SO(3) maps) rotate with the patches: not exactly (the patch signal is not band-limited and
    ReLU acts on the grid), but within ``tol`` and far closer than another patch's maps."""
    p = surfaces()
    variables = reference.init(model, p)
    errs, unrelated = map_equivariance(jax.jit(lambda x: maps(model, variables, x)), p)
    with capsys.disabled():
        print(f"\n  {label} equivariance, relative error: {errs.round(3)}; against other "
              f"patches: {unrelated.round(3)}")
    assert errs.max() < tol and errs.max() < unrelated.min() / 4
