"""SOUND: the descriptor map rotates with the patch, and the fused inference trunk (the shared
S2 layer handing its spectrum to both branches) equals the layer-by-layer network."""
import pytest
import jax
import jax.numpy as jnp
import numpy as np

from sphere_jax.models.sound import Sound, SoundOut
from tests.models import _helpers
from tests import reference
from tests.reference import rel_err


def test_sound_descriptor_map_is_equivariant(capsys):
    model = Sound(s2_bandwidths=(8, 8), s2_features=6, descriptor_bandwidths=(8, 6, 4),
                  descriptor_features=(6, 1), lrf_bandwidths=(8, 8, 8), lrf_features=(4, 1),
                  decoder_side=4, decoder_hidden=(8, 8, 8))
    _helpers.assert_maps_equivariant("SOUND descriptor map (B 8->4)", model,
                                     lambda m, v, x: m.apply(v, x).maps, capsys)


@pytest.mark.slow
def test_sound_fused_trunk_equals_layer_by_layer():
    rng = np.random.default_rng(6)
    # Descriptor branch at lower bandwidth than the LRF branch: the shared trunk's spectrum is
    # truncated for it.
    model = Sound(s2_bandwidths=(8, 8), s2_features=3, descriptor_bandwidths=(8, 6, 4),
                  descriptor_features=(3, 1), lrf_bandwidths=(8, 8, 8), lrf_features=(2, 1),
                  decoder_side=4, decoder_hidden=(8, 8, 8))
    p = jnp.asarray(rng.normal(size=(3, 64, 3)) * 0.4, jnp.float32)
    variables = reference.init(model, p, train=False)
    variables = reference.shifted_batch_stats(variables, rng)
    want = reference.apply(model.clone(fused=False), variables, p, train=False)
    got = jax.jit(lambda v, p: model.apply(v, p, train=False))(variables, p)
    assert isinstance(got, SoundOut)
    assert rel_err(got.maps, want.maps) < 1e-5
    assert float(jnp.abs(got.rotations - want.rotations).max()) < 1e-4
