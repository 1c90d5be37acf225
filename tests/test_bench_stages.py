"""The stages benchmark profiles the shipped networks themselves: its stages, chained, give
the bundle's own output."""
import numpy as np
import pytest

from experiments.benchmarks import stages
from sphere_jax.bundles import inference
from sphere_jax.models import shipped


@pytest.mark.slow
@pytest.mark.parametrize("kind", stages.KINDS)
def test_stages_chain_to_the_networks_output(kind):
    bundle = inference.cached_bundle(shipped.bundle_path(kind, required=True))
    rng = np.random.default_rng(0)
    x = (rng.normal(size=(4, bundle.config.data.n_points, 3)) * 0.4).astype(np.float32)
    frames = np.broadcast_to(np.eye(3, dtype=np.float32), (4, 3, 3))
    parts, final = stages.stages(bundle, x, frames)
    whole = stages.whole_network(bundle, x, frames)
    whole = whole.fn(*whole.args)
    assert np.max(np.abs(np.asarray(final) - np.asarray(whole))) < 1e-4
    assert [p.name for p in parts][:2] == ["signal", "S2 analysis"]
    m = bundle.model
    steps = (1 + len(m.descriptor_features) - 1 + len(m.lrf_features) - 1 if kind == "sound"
             else len(m.features) - 1)           # SOUND: the shared layer's and each branch's
    assert sum("pointwise" in p.name for p in parts) == steps
