"""The LEAD ablation task: its variants are the seed's configurations, the Pareto front, and
one tiny end-to-end run (train, time, evaluate, table and plot)."""
import os
import shutil

import numpy as np
import pytest

from configs import ablation
from sphere_jax.eval import ablation as task

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop


def test_variants_are_the_seeds_configurations():
    c = ablation.get_config("")
    f = task.variant_config(c, "F")
    assert f.model_kwargs.bandwidths == (24, 12, 8, 6, 4)      # SO(3) layers read 12, 8, 6
    assert f.model_kwargs.features == (40, 40, 40, 1)
    k = task.variant_config(c, "K")
    assert k.model_kwargs.bandwidths[1:4] == (16, 12, 8) and k.model_kwargs.features[0] == 20
    a = task.variant_config(c, "A")
    assert a.model_kwargs.bandwidths == (24, 16, 12, 8, 6, 4)
    assert task.variant_config(c, "B").model_kwargs.grid == "equatorial"
    for name in c.variants:                       # same budget and data for every variant
        v = task.variant_config(c, name)
        assert v.train.steps == c.budget_steps and v.train.batch_size == c.batch_size
        assert v.data.root == c.train_data.root
        assert "redkitchen" not in v.data.root and "bunny" not in v.data.root


def test_pareto_front():
    times = np.array([1.0, 0.5, 0.7, 0.3, 0.9])
    recall = np.array([0.9, 0.8, 0.7, 0.6, 0.95])
    assert task.pareto_front(times, recall) == [3, 1, 4]      # fastest first; 2 and 0 dominated


def test_tiny_ablation_end_to_end(tmp_path):
    c = ablation.get_config("tiny")
    rows, md = task.run(c, str(tmp_path), progress=False)
    assert [r["variant"] for r in rows] == ["A", "B"]
    assert rows[0]["relative_time"] == 1.0
    assert rows[1]["params"] < rows[0]["params"]               # two SO(3) layers fewer
    assert all(0.0 <= r["fmr"] <= 1.0 and r["train_s"] > 0 for r in rows)
    assert "LEAD ablation" in md
    assert (tmp_path / "ablation.csv").read_text().count("\n") == 3
    assert os.path.getsize(tmp_path / "ablation_pareto.png") > 5000
    shutil.rmtree(tmp_path / "variants" / "B" / "eval")
    again, _ = task.run(c, str(tmp_path), progress=False)     # trained and scored: reused
    assert not (tmp_path / "variants" / "B" / "eval").exists()
    assert [r["train_s"] for r in again] == [r["train_s"] for r in rows]
    assert [r["inlier_ratio"] for r in again] == [r["inlier_ratio"] for r in rows]
