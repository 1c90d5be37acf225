"""LEAD-PN (thesis 4.1, ablation): LEAD with a PointNet encoder on patches already oriented by
an LRF (FLARE), so the code is rotation invariant through the frame, not by equivariance."""
from __future__ import annotations

from typing import NamedTuple, Sequence

import flax.linen as nn
import jax

from sphere_jax.models import flare, lead
from sphere_jax.models.folding import FoldingDecoder
from sphere_jax.models.pointnet import PointNetEncoder
from sphere_jax.models.spec import ModelSpec


class LeadPNOut(NamedTuple):
    codes: jax.Array            # [N, D]
    reconstructions: jax.Array  # [N, M, 3]


class LeadPN(nn.Module):
    """``__call__(oriented patches [N, P, 3], train) -> LeadPNOut``."""
    features: Sequence[int] = (64, 128, 512)
    decoder_side: int = 35
    decoder_hidden: Sequence[int] = (514, 257, 128)
    axis_name: str | None = None    # data-parallel batch axis of the batch norms

    @nn.compact
    def __call__(self, patches, train: bool = False):
        code = PointNetEncoder(self.features, self.axis_name)(patches, train)
        decoder = FoldingDecoder(self.decoder_side, self.decoder_hidden, self.axis_name)
        return LeadPNOut(code, decoder(code, train))


def oriented(batch):
    """Network input: each patch in its FLARE frame."""
    return flare.flare_orient(batch["patches"])


def describe(model, variables, patches, frames=None):
    return model.apply(variables, flare.flare_orient(patches), train=False).codes


# PointNet at inference goes patch by patch already (pointnet.inference_codes): slicing the
# chunk as well made it 5-13 % slower.
SPEC = ModelSpec(kind="lead_pn", module=LeadPN, outputs=LeadPNOut, loss=lead.loss,
                 inputs=oriented, describe=describe, infer_slice=None,
                 frozen_batch_norm=True)
