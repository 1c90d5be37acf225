"""The bundles in ``sphere_jax/weights`` (the shipped ones and any kept beside them) state
what they were trained on, and none was trained on an evaluation scene: the
redkitchen fragments (``demo_fullres`` is redkitchen 0 and 1) and the bunny are test scans."""
import glob
import os

import pytest

from sphere_jax import bundle, paths

EVALUATION_SCENES = ("redkitchen", "demo_fullres", "bunny", "stanford")
ROOT = paths.weights_root()
BUNDLES = sorted(os.path.dirname(p) for p in
                 glob.glob(os.path.join(ROOT, "**", "bundle", "config.json"), recursive=True))


def _name(path):
    return os.path.relpath(os.path.dirname(path), ROOT)


def test_every_shipped_kind_is_checked_here():
    assert set(paths.SHIPPED.values()) <= {_name(p) for p in BUNDLES}


@pytest.mark.parametrize("path", BUNDLES, ids=_name)
def test_no_bundle_saw_an_evaluation_scene(path):
    stated = " ".join(bundle.read_training_data(path)["folders"]).lower()
    configured = str(bundle.read_config(path).data.get("root", "")).lower()
    seen = [s for s in EVALUATION_SCENES if s in stated or s in configured]
    assert not seen, f"{_name(path)} was trained on evaluation scans: {seen}"
