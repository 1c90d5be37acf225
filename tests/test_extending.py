"""Adding a model kind is one module and one registry line; adding a hand-crafted descriptor is
one function and one registry row (CONTRIBUTING.md). A toy of each runs through train,
describe, register and evaluate.

The toys are registered for one test only, with pytest's ``monkeypatch``: it puts the kind in
``models.SPECS`` and the rows in ``registry.METHODS`` and restores both at teardown, so no
other test sees them (the registries are read at each call, never copied at import).
"""
from __future__ import annotations

import json
import os
from typing import NamedTuple

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sphere_jax
from configs import eval_registration, lead_pn
from sphere_jax import align, checks, models, training
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import io
from sphere_jax.eval import tasks
from sphere_jax.features import builders, registry
from sphere_jax.models import flare
from sphere_jax.models.spec import ModelSpec
from tests.data.generators.test_synthetic import SMALL


# --- what a new model kind's file holds ---------------------------------------------------

class ToyOut(NamedTuple):
    codes: jax.Array            # [N, D]


class Toy(nn.Module):
    """A point-wise layer and a max pool over FLARE-oriented patches."""
    width: int = 8
    axis_name: str | None = None    # every model takes the data-parallel axis

    @nn.compact
    def __call__(self, patches, train: bool = False):
        return ToyOut(jnp.max(nn.Dense(self.width)(patches), axis=1))


def toy_loss(out: ToyOut, batch, config):
    spread = jnp.mean(jnp.var(out.codes, axis=0))        # codes that tell patches apart
    return 1.0 / (1.0 + spread), {"spread": spread}


def toy_describe(model, variables, patches, frames=None):
    return model.apply(variables, flare.flare_orient(patches)).codes


TOY = ModelSpec(kind="toy", module=Toy, outputs=ToyOut, loss=toy_loss,
                inputs=lambda batch: flare.flare_orient(batch["patches"]),
                describe=toy_describe)


# --- what a new hand-crafted descriptor is --------------------------------------------------

def distance_histogram(fragment, radius, bins=8):
    """``[K, bins]``: the share of each keypoint's neighbours in each shell of its support."""
    nb = builders.neighbourhoods(fragment, fragment.keypoints, radius)
    shell = np.minimum((nb.dist / radius * bins).astype(int), bins - 1)
    hist = np.zeros((nb.n_keypoints, bins))
    np.add.at(hist, (nb.owner, shell), 1.0)
    return hist / np.maximum(hist.sum(1, keepdims=True), 1.0)


ROWS = (registry.Method("toy", "toy", ("toy",), "Toy", build=builders.network("toy")),
        registry.Method("dist_hist", "dist_hist", (), "Distance histogram",
                        build=builders.per_fragment(distance_histogram)))


def register_toys(monkeypatch):
    monkeypatch.setitem(models.SPECS, "toy", TOY)
    monkeypatch.setattr(registry, "METHODS", registry.METHODS + ROWS)


@pytest.fixture
def toys(monkeypatch):
    register_toys(monkeypatch)


@pytest.fixture(scope="module")
def rooms(tmp_path_factory):
    root = tmp_path_factory.mktemp("toy_rooms")
    synthetic.make_all(str(root), seed=5, n_scenes=1, **SMALL)
    return root / "3dmatch"


@pytest.mark.slow                   # a training run, a registration and an evaluation
def test_a_toy_kind_and_descriptor_train_describe_register_and_evaluate(toys, rooms,
                                                                      tmp_path):
    c = lead_pn.get_config("tiny")
    c.model, c.model_kwargs = "toy", {"width": 8}
    c.data.update(root=str(rooms), voxel=0.04, radius=0.5, keypoint_leaf=0.5)
    c.train.update(steps=2, log_every=1, eval_every=2, checkpoint_every=2)
    training.train_and_evaluate(c, str(tmp_path / "train"), progress=False)
    bundle = str(tmp_path / "train" / "bundle")
    assert sphere_jax.load_bundle(bundle).kind == "toy"

    clouds = [str(rooms / "synth-room-0" / f"cloud_bin_{i}.ply") for i in (0, 1)]
    points = io.read_points(clouds[0]).points
    keypoints = np.random.default_rng(0).choice(len(points), 40, replace=False)
    desc = sphere_jax.describe(bundle, points, keypoints, radius=0.5)
    assert desc.shape == (40, 8) and np.isfinite(desc).all() and desc.std(0).max() > 0

    for method, given in (("toy", bundle), ("dist_hist", None)):
        result = align.register(clouds[0], clouds[1], method=method, bundle=given,
                                n_keypoints=300, voxel=0.04, radius=0.5, icp=False)
        assert result.method == method and result.keypoints[0][0] > 0

    ev = eval_registration.get_config("tiny")
    ev.methods, ev.bundles.toy = "toy,dist_hist,fpfh", bundle
    ev.data.update(root=str(rooms), voxel=0.04, radius=0.5)
    rows, _ = tasks.run(ev, str(tmp_path / "eval"), progress=False)
    got = {r["method"]: r for r in rows}
    assert {"toy", "dist_hist", "fpfh"} <= set(got)
    assert all(0.0 <= float(got[m]["inlier_ratio"]) <= 1.0 for m in ("toy", "dist_hist"))
    record = json.load(open(os.path.join(tmp_path, "eval", tasks.RUN_RECORD)))
    assert set(record["bundles"]) == {"toy"}


def test_toys_registered_by_monkeypatch_leave_no_trace():
    with pytest.MonkeyPatch.context() as mp:
        register_toys(mp)
        assert models.spec("toy") is TOY and registry.needs("toy") == ("toy",)
        assert registry.resolve("dist_hist").label == "Distance histogram"
    assert "toy" not in models.SPECS and "dist_hist" not in registry.keys()
    with pytest.raises(checks.InputError):
        registry.resolve("toy")
