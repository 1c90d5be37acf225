"""LEAD: the encoder's SO(3) descriptor map rotates with the patch."""
import jax

from sphere_jax import models
from tests.models import _helpers


def test_lead_encoder_is_equivariant(capsys):
    """maps(R·P) vs L_R maps(P) for the same points: the whole encoder (signal, convolutions,
    batch norm, ReLU) commutes with rotations up to the grid's discretisation."""
    model = models.Lead(bandwidths=(8, 6, 5, 4, 4, 4), features=(8, 8, 8, 8, 1),
                        decoder_side=4, decoder_hidden=(8, 8, 8))
    p = _helpers.surfaces()
    variables = model.init(jax.random.PRNGKey(0), p)
    encode = jax.jit(lambda x: model.apply(variables, x, method="encode"))
    errs, unrelated = _helpers.map_equivariance(encode, p)
    with capsys.disabled():
        print(f"\n  LEAD encoder (B 8->4) equivariance, relative error: {errs.round(3)}; "
              f"against other patches: {unrelated.round(3)}")
    # Not exact: the patch signal is not band-limited and ReLU acts on the grid.
    assert errs.max() < 0.25 and errs.max() < unrelated.min() / 4


def test_lead_outputs_are_named():
    model = models.Lead(bandwidths=(4, 4, 4, 4, 4, 4), features=(2, 2, 2, 2, 1),
                        decoder_side=3, decoder_hidden=(4, 4, 4))
    p = _helpers.surfaces(2, 64)
    out = model.apply(model.init(jax.random.PRNGKey(0), p), p)
    assert isinstance(out, models.LeadOut)
    assert out.maps.shape == (2, 8, 8, 8) and out.reconstructions.shape == (2, 9, 3)
