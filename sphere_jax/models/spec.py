"""What the trainer and the inference API know of a model kind: one :class:`ModelSpec` per
``models/<kind>.py``, registered by kind in :mod:`sphere_jax.models`.

A spec answers every question that used to be an ``if config.model == ...`` chain: which module
to build, what the network reads from a batch, what the batch must carry (rotated copies,
labels), the loss, and how a trained model orients or describes patches.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, NamedTuple, Optional

import flax.linen as nn

# (outputs, batch, config) -> (loss, metrics); ``batch['inputs']`` is what the network read.
LossFn = Callable[[NamedTuple, dict, Any], tuple]
# (model, variables, unit patches [K, N, 3]) -> rotations [K, 3, 3] (columns x̂, ŷ, ẑ)
OrientFn = Callable[[nn.Module, dict, Any], Any]
# (model, variables, unit patches [K, N, 3], k) -> the k strongest frames [K, k, 3, 3]
OrientModesFn = Callable[[nn.Module, dict, Any, int], Any]
# (model, variables, unit patches [K, N, 3], frames [K, 3, 3] or None) -> descriptors [K, D]
DescribeFn = Callable[[nn.Module, dict, Any, Any], Any]


def _patches(batch):
    return batch["patches"]


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """One model kind.

    Attributes:
      kind: the name configs use (``config.model``).
      module: the flax module; built as ``module(**config.model_kwargs)`` unless ``build``;
        it takes ``axis_name``, the data-parallel axis its batch norms average over.
      outputs: the NamedTuple its ``__call__`` returns.
      loss: its self-supervised (or supervised) loss, :data:`LossFn`.
      inputs: batch -> the array the network reads (default ``batch['patches']``).
      input_key: the batch field that sets the network's input shape at initialisation.
      copies: batches carry a rotated, occluded copy of each patch and its rotation.
      labelled: trained on shape labels (batches of ``points`` and ``labels``).
      orient / describe: inference on unit patches (None: the kind does not do it).
      orient_modes: the strongest frames of an orienting kind, first ``orient``'s (frame
        hypotheses; None: one frame only).
      describe_frames: ``describe`` turns its output by LRFs (FLARE unless given).
      frozen_batch_norm: adapting to new scans keeps the bundle's running moments (an
        autoencoder fitted with each batch's moments fits another function than the one
        it evaluates; :mod:`sphere_jax.training.adaptation`).
      build: config -> module, for modules that need more than ``model_kwargs``.
      infer_slice: patches per step inside one jitted call at inference
        (:func:`sphere_jax.parallel.in_slices`); None: the whole chunk in one step.
    """
    kind: str
    module: type
    outputs: type
    loss: LossFn
    inputs: Callable[[dict], Any] = _patches
    input_key: str = "patches"
    copies: bool = False
    labelled: bool = False
    orient: Optional[OrientFn] = None
    describe: Optional[DescribeFn] = None
    orient_modes: Optional[OrientModesFn] = None
    describe_frames: bool = False
    frozen_batch_norm: bool = False
    build: Optional[Callable[[Any], nn.Module]] = None
    # The spherical networks' spectra for a 256-patch chunk are 68-270 MB per layer, mapped
    # afresh on every call (350 page faults per patch for Compass); for 32 patches they stay
    # in the cache. Compass and SOUND describe about 10 % faster so on 2 cores.
    infer_slice: Optional[int] = 32

    def make(self, config) -> nn.Module:
        """The flax module of ``config``."""
        if self.build is not None:
            return self.build(config)
        return self.module(**dict(config.model_kwargs))

    @property
    def orients(self) -> bool:
        """Gives local reference frames (an LRF model)."""
        return self.orient is not None

    @property
    def describes(self) -> bool:
        """Gives local descriptors."""
        return self.describe is not None
