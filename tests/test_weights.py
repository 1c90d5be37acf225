"""The bundles in ``sphere_jax/weights``: none was trained on an evaluation scene (the rule of
:mod:`sphere_jax.data.held_out`), and each shipped one is what its config's one
command produces."""
import glob
import importlib
import json
import os

import pytest

from sphere_jax import paths
from sphere_jax.bundles import store
from sphere_jax.data import held_out, scan_roots
from sphere_jax.models import shipped

ROOT = paths.weights_root()
BUNDLES = sorted(os.path.dirname(p) for p in
                 glob.glob(os.path.join(ROOT, "**", "bundle", "config.json"), recursive=True))
# How a run was split over machines, not what it is.
RUN_FIELDS = ("steps_done", "init_bundle", "time_budget_s", "devices", "pack")


def _name(path):
    return os.path.relpath(os.path.dirname(path), ROOT)


def test_every_shipped_kind_is_checked_here():
    assert {row.folder for row in shipped.SHIPPED.values()} <= {_name(p) for p in BUNDLES}


@pytest.mark.parametrize("path", BUNDLES, ids=_name)
def test_no_bundle_saw_an_evaluation_scene(path):
    stated = store.read_training_data(path)
    configured = scan_roots.root_entries(store.read_config(path).data.get("root", ""))
    seen = held_out.scenes_of(list(stated["folders"]) + configured)
    seen += stated.get("evaluation_scenes", [])
    assert not seen, f"{_name(path)} was trained on evaluation scans: {seen}"


def _comparable(config):
    c = json.loads(json.dumps(config.to_dict()))
    for key in RUN_FIELDS:
        c["train"].pop(key, None)
    c.pop("n_classes", None)            # a classifier's: counted from its data by training
    return c


def test_every_shipped_bundle_has_a_recipe():
    for name, row in shipped.SHIPPED.items():
        assert os.path.isfile(os.path.join(paths.REPO, "configs", f"{row.recipe}.py")), name
        config = store.read_config(shipped.bundle_path(name, required=True))
        assert config.model == row.kind, name


@pytest.mark.parametrize("name", sorted(shipped.SHIPPED))
def test_shipped_bundle_is_what_its_command_trains(name):
    """``python -m experiments.train --config=RECIPE:mid`` reproduces the shipped bundle: its
    config (fields, data and schedule) is the command's config."""
    config = store.read_config(shipped.bundle_path(name, required=True))
    recipe = importlib.import_module(f"configs.{shipped.SHIPPED[name].recipe}").get_config("mid")
    assert _comparable(config) == _comparable(recipe)
