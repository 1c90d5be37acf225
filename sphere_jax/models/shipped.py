"""The bundles the package ships (``sphere_jax/weights/<folder>/bundle``): one row per name,
with its folder, its model kind and the config whose 'mid' size is its whole recipe
(``python -m experiments.train --config=<recipe>:mid`` trains it; tests/test_weights.py).

A name that is a model kind is that kind's default: the bundle the descriptors and LRFs of
:mod:`sphere_jax.features.registry` load unless given another.
"""
from __future__ import annotations

import os
from typing import NamedTuple

from sphere_jax import checks, paths


class Shipped(NamedTuple):
    folder: str         # under paths.weights_root()
    kind: str           # config.model (sphere_jax.models.SPECS)
    recipe: str         # configs/<recipe>.py


SHIPPED = {
    # Compass on the clean real scans: more repeatable on the validation pairs than on the
    # synthetic rooms, and LEAD matches better in its frames (docs/training.md).
    "compass": Shipped("compass_real_mid", "compass", "compass_real"),
    "lead": Shipped("lead_mid", "lead", "lead"),
    "lead_pn": Shipped("lead_pn_mid", "lead_pn", "lead_pn"),
    "sound": Shipped("sound_mid", "sound", "sound"),
    "compass_rooms": Shipped("compass_mid", "compass", "compass"),
    # FLARE's ẑ and a learned x̂ (docs/training.md): more repeatable than FLARE, less than
    # Compass on the validation pairs; shipped so that lead@lrf_net can be compared.
    "lrf_net": Shipped("lrf_net_mid", "lrf_net", "lrf_net"),
    "compass_shapes": Shipped("compass_shapes_mid", "compass", "compass_shapes"),
    "pointnet": Shipped("pointnet_mid", "classify", "classify"),
    "compass_pointnet": Shipped("compass_pointnet_mid", "classify", "classify_compass"),
    "compass_pointnet_rotated": Shipped("compass_pointnet_rotated_mid", "classify",
                                        "classify_compass_rotated"),
}


def bundle_path(name, required=False) -> str:
    """The bundle folder of shipped bundle ``name`` (a name of :data:`SHIPPED`, or a folder of
    ``sphere_jax/weights/``); ``''`` when it is absent (an error instead with ``required``)."""
    folder = SHIPPED[name].folder if name in SHIPPED else name
    path = os.path.join(paths.weights_root(), folder, "bundle")
    if os.path.isfile(os.path.join(path, "config.json")):
        return path
    if required:
        raise checks.MissingError(f"no shipped bundle {folder!r} in {paths.weights_root()} "
                                  f"(the package's weights; $SPHERE_JAX_WEIGHTS replaces them)")
    return ""


def defaults() -> dict:
    """``{kind: bundle folder}``: the default bundle of every model kind that has one (the
    rows named for their kind), absent ones as ``''``."""
    return {name: bundle_path(name) for name, row in SHIPPED.items() if name == row.kind}
