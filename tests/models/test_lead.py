"""LEAD: the encoder's SO(3) descriptor map rotates with the patch."""

from sphere_jax import models
from tests import reference
from tests.models import _helpers


def test_lead_encoder_is_equivariant(capsys):
    """maps(R·P) vs L_R maps(P) for the same points: the whole encoder (signal, convolutions,
    batch norm, ReLU) commutes with rotations up to the grid's discretisation."""
    model = models.Lead(bandwidths=(8, 6, 5, 4, 4, 4), features=(8, 8, 8, 8, 1),
                        decoder_side=4, decoder_hidden=(8, 8, 8))
    _helpers.assert_maps_equivariant("LEAD encoder (B 8->4)", model, lambda m, v, x: m.apply(
        v, x, method="encode"), capsys)


def test_lead_outputs_are_named():
    model = models.Lead(bandwidths=(4, 4, 4, 4, 4, 4), features=(2, 2, 2, 2, 1),
                        decoder_side=3, decoder_hidden=(4, 4, 4))
    p = _helpers.surfaces(2, 64)
    out = reference.apply(model, reference.init(model, p), p)
    assert isinstance(out, models.LeadOut)
    assert out.maps.shape == (2, 8, 8, 8) and out.reconstructions.shape == (2, 9, 3)
