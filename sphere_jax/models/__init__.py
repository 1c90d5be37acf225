"""flax models of the thesis and their specs: Compass, LEAD, LEAD-PN, SOUND, and a PointNet
classifier.

Each ``models/<kind>.py`` holds one model kind: its flax module, the NamedTuple of its outputs,
its loss, what its batches need and how it orients or describes patches, gathered in a
:class:`~sphere_jax.models.spec.ModelSpec`. The trainer (:mod:`sphere_jax.training`) and the
inference API (:mod:`sphere_jax.bundles.inference`) look the spec up by ``config.model``;
adding a model is adding one file and one line here. The bundles the package ships:
:mod:`sphere_jax.models.shipped`.

Models take patches normalised to the unit ball (local coordinates divided by the support
radius) and compute their spherical signals themselves, so that the inference API and the
training step share one code path.
"""
from sphere_jax import checks
from sphere_jax.models import classify, compass, lead, lead_pn, lrf_net, sound
from sphere_jax.models.classify import ClassifyOut, PointNetClassifier
from sphere_jax.models.compass import Compass, CompassOut
from sphere_jax.models.lead import Lead, LeadOut
from sphere_jax.models.lead_pn import LeadPN, LeadPNOut
from sphere_jax.models.pointnet import PointNetEncoder
from sphere_jax.models.sound import Sound, SoundOut
from sphere_jax.models.spec import ModelSpec

SPECS = {s.kind: s for s in (compass.SPEC, lead.SPEC, lead_pn.SPEC, sound.SPEC, classify.SPEC,
                             lrf_net.SPEC)}


def spec(kind: str) -> ModelSpec:
    """The spec of model kind ``kind`` (``config.model``)."""
    if kind not in SPECS:
        raise checks.ConfigError("config.model", f"one of {', '.join(SPECS)}", kind)
    return SPECS[kind]


def build(config):
    """The flax module of a training or bundle config."""
    return spec(config.model).make(config)


__all__ = ["ClassifyOut", "Compass", "CompassOut", "Lead", "LeadOut", "LeadPN", "LeadPNOut",
           "ModelSpec", "PointNetClassifier", "PointNetEncoder", "SPECS", "Sound", "SoundOut",
           "build", "spec"]
