"""flax models of the thesis: Compass, LEAD, LEAD-PN, SOUND, and a PointNet classifier.

Models take patches normalised to the unit ball (local coordinates divided by the support
radius) and compute their spherical signals themselves, so that the inference API and the
training step share one code path.
"""
from sphere_jax.models.compass import Compass
from sphere_jax.models.lead import Lead, LeadPN
from sphere_jax.models.pointnet import PointNetClassifier, PointNetEncoder
from sphere_jax.models.sound import Sound

__all__ = ["Compass", "Lead", "LeadPN", "PointNetClassifier", "PointNetEncoder", "Sound"]
