"""The folding decoder against a NumPy reference of the AtlasNet MLP on ``[grid, code]``."""
import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax.models.folding import FoldingDecoder, unit_grid


def _reference(variables, code, grid):
    """The decoder as written in the papers: concatenate, then Dense/BN/ReLU per point (float64,
    inference batch norm)."""
    p, st = variables["params"], variables["batch_stats"]
    x = np.concatenate([np.broadcast_to(grid, (len(code),) + grid.shape),
                        np.broadcast_to(code[:, None], (len(code), len(grid), code.shape[1]))],
                       -1).astype(np.float64)
    for k in range(3):
        x = x @ np.asarray(p[f"Dense_{k}"]["kernel"]) + np.asarray(p[f"Dense_{k}"]["bias"])
        bn, s = p[f"BatchNorm_{k}"], st[f"BatchNorm_{k}"]
        x = (x - np.asarray(s["mean"])) / np.sqrt(np.asarray(s["var"]) + 1e-5)
        x = np.maximum(x * np.asarray(bn["scale"]) + np.asarray(bn["bias"]), 0)
    return np.tanh(x @ np.asarray(p["Dense_3"]["kernel"]) + np.asarray(p["Dense_3"]["bias"]))


def test_split_first_layer_matches_the_concatenated_mlp():
    rng = np.random.default_rng(0)
    code = rng.normal(size=(5, 10)).astype(np.float32)
    model = FoldingDecoder(6, (16, 8, 4))
    v = model.init(jax.random.key(0), jnp.asarray(code), train=False)
    # Non-trivial statistics and affine parameters, so every term of the map is exercised.
    v = jax.tree.map(lambda a: a + jnp.asarray(rng.uniform(0.2, 0.8, a.shape), a.dtype), v)
    out = np.asarray(model.apply(v, jnp.asarray(code), train=False))
    assert out.shape == (5, 36, 3)
    err = np.abs(out - _reference(v, code, unit_grid(6))).max()
    assert err < 1e-5, err
