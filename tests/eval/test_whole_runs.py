"""Whole evaluation runs at 'tiny' size: files, columns, means, plots, errors, resuming."""
import csv
import json
import os

import pytest

from configs import eval_lrf, eval_registration
from sphere_jax import checks
from sphere_jax.eval import pair_sets, report, tasks
from sphere_jax.features import methods


def _read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_registration_tiny_writes_results(tmp_path, shared):
    c = eval_registration.get_config("tiny")
    c.data.root = os.path.join(shared, "3dmatch", "7-scenes-redkitchen")
    c.methods = "fpfh,shot,lead,lead_gt,shot_gt,shot_vote"
    rows, md = tasks.run(c, str(tmp_path), progress=False)
    table = _read_csv(tmp_path / "results.csv")
    assert tuple(table[0]) == report.REGISTRATION_COLUMNS
    means = {r["method"]: r for r in table if r["scene"] == "mean"}
    assert list(means) == ["fpfh", "shot", "lead", "lead_gt", "shot_gt", "shot_vote"]
    print({m: r["inlier_ratio"] for m, r in means.items()})
    assert {r["scene"] for r in table} == {"7-scenes-redkitchen", "mean"}
    assert all(int(r["pairs"]) == 2 for r in table)
    for r in table:
        assert 0.0 <= float(r["fmr"]) <= 1.0 and 0.0 <= float(r["inlier_ratio"]) <= 1.0
        assert float(r["ms_per_keypoint"]) > 0
    assert "Feature-match recall" in md and (tmp_path / "fmr_vs_tau2.png").stat().st_size > 5000
    # The vote finds both pairs' rotations, and SHOT described in the voted frames matches
    # far better than in its LRFs (0.49 against 0.19 measured at these 300 keypoints).
    votes = _read_csv(tmp_path / "votes.csv")
    assert [v["method"] for v in votes] == ["shot_vote"] * 2
    assert all(float(v["vote_rre_deg"]) < 10.0 and
               0 < int(v["vote_support"]) <= int(v["vote_proposals"]) for v in votes)
    assert all(0 <= int(v["vote_mode"]) < c.vote_hypotheses and
               float(v["box_turn_deg"]) in (0.0, 90.0, 120.0, 180.0) for v in votes)
    assert float(means["shot_vote"]["inlier_ratio"]) > 1.5 * float(means["shot"]["inlier_ratio"])


@pytest.mark.slow
def test_lrf_tiny_on_stanford_layout(tmp_path, shared):
    c = eval_lrf.get_config("stanford")
    c.data.update(root=os.path.join(shared, "stanford", "bunny", "data"), n_keypoints=200,
                  max_pairs=2)
    c.methods = "flare,shot,toldi,compass"
    c.plot_pairs = 1
    rows, _ = tasks.run(c, str(tmp_path), progress=False)
    table = _read_csv(tmp_path / "lrf_results.csv")
    assert tuple(table[0]) == report.LRF_COLUMNS
    means = {r["method"]: float(r["rep"]) for r in table if r["scene"] == "mean"}
    assert set(means) == {"flare", "shot", "toldi", "compass"}
    assert means["flare"] > 0.1 and means["shot"] > 0.1, means
    pngs = os.listdir(tmp_path / "plots")
    assert len(pngs) == 4 and all(p.endswith(".png") for p in pngs)


def test_bad_config_values_are_named():
    c = eval_registration.get_config("tiny")
    c.methods = "fpfh,nonsense"
    with pytest.raises(checks.ConfigError, match="config.methods .* .nonsense unknown."):
        tasks.chosen_methods(c, ("fpfh", "shot"), {})
    c.data.root = "/no/such/folder"
    with pytest.raises(FileNotFoundError, match="/no/such/folder"):
        pair_sets.pair_sets(c)
    c.bundle = "/no/such/bundle"
    with pytest.raises(checks.ConfigError, match="config.bundle must be a bundle folder"):
        tasks.bundle_paths(c)
    c.methods = "fpfh,lead_pn"
    with pytest.warns(UserWarning, match="lead_pn"):
        assert tasks.chosen_methods(c, ("fpfh", "lead_pn"), {}) == ["fpfh"]


def test_registration_tiny_on_embedded_scenes_rotated(tmp_path):
    """The default data (no ../shared needed), rotated variant: runs and fills every scene."""
    c = eval_registration.get_config("tiny")
    c.rotate = True
    rows, md = tasks.run(c, str(tmp_path), progress=False)
    assert {r["scene"] for r in rows} == {"synth-room-0", "synth-room-1"}
    assert "(rotated)" in md


def test_partial_scene_and_ground_truth_elsewhere(tmp_path):
    """A scene holding only fragments 8 and 15 is found, and with ``gt_root`` (the 3DLoMatch
    release layout: ground truth only) its pairs come from there; the pair whose cloud is
    absent is skipped with a warning."""
    import numpy as np
    from sphere_jax.data.readers import io, threedmatch
    scene = tmp_path / "scans" / "kitchen"
    scene.mkdir(parents=True)
    pts = np.random.default_rng(0).uniform(-1, 1, (500, 3)).astype(np.float32)
    for k in (8, 15):
        io.write_ply(str(scene / f"cloud_bin_{k}.ply"), pts)
    t = np.eye(4)
    t[:3, 3] = [0.1, 0.0, 0.0]
    lo = tmp_path / "lomatch" / "kitchen-evaluation"
    lo.mkdir(parents=True)
    threedmatch.write_gt_log(str(lo / "gt.log"), {(8, 15): t, (3, 8): t}, 20)
    with pytest.raises(ValueError, match="no gt.log"):
        pair_sets.find_pair_sets(tmp_path / "scans")                  # none beside the clouds
    with pytest.warns(UserWarning, match="1 ground-truth pair"):
        sets = pair_sets.find_pair_sets(tmp_path / "scans", gt_root=tmp_path / "lomatch")
    assert [(s.name, s.pairs) for s in sets] == [("kitchen", [(8, 15)])]
    np.testing.assert_allclose(sets[0].transforms[(8, 15)], t)
    with pytest.raises(FileNotFoundError, match="data.gt"):
        pair_sets.find_pair_sets(tmp_path / "scans", gt_root=tmp_path / "nowhere")


def test_a_killed_evaluation_redoes_only_what_it_had_not_finished(tmp_path, monkeypatch):
    """The run dies in its second method: the rerun describes with that method only and writes
    the same results.csv (timings aside) as an uninterrupted run; another config starts
    afresh."""
    c = eval_registration.get_config("tiny")
    c.methods = "fpfh,shot"
    c.data.scenes = "synth-room-0"                          # one scene: methods in order
    tasks.run(c, str(tmp_path / "whole"), progress=False)
    calls = []
    real = methods.descriptor

    def counting(name, *args, **kwargs):
        describe = real(name, *args, **kwargs)

        def run(fragment):
            calls.append(name)
            if name == "shot" and die:
                raise KeyboardInterrupt                      # the kill
            return describe(fragment)
        return run

    monkeypatch.setattr(methods, "descriptor", counting)
    die = True
    with pytest.raises(KeyboardInterrupt):
        tasks.run(c, str(tmp_path / "cut"), progress=False)
    assert calls == ["fpfh"] * calls.count("fpfh") + ["shot"] and calls.count("fpfh") > 0
    calls.clear()
    die = False
    tasks.run(c, str(tmp_path / "cut"), progress=False)
    assert set(calls) == {"shot"}                            # fpfh was kept
    record = lambda run: json.loads((tmp_path / run / "run.json").read_text())
    assert record("cut")["resumed"] and not record("whole")["resumed"]
    strip = lambda rows: [{k: v for k, v in r.items() if k not in report.TIMING_COLUMNS}
                          for r in rows]
    assert strip(_read_csv(tmp_path / "cut" / "results.csv")) == \
        strip(_read_csv(tmp_path / "whole" / "results.csv"))
    calls.clear()
    c.data.n_keypoints = 200                                 # another config: all again
    tasks.run(c, str(tmp_path / "cut"), progress=False)
    assert set(calls) == {"fpfh", "shot"}


def test_a_killed_lrf_evaluation_redoes_only_what_it_had_not_finished(tmp_path, monkeypatch):
    """The LRF benchmark resumes as the registration one does: the run dies in its second
    method, the rerun orients with that method only and writes the same lrf_results.csv."""
    c = eval_lrf.get_config("tiny")
    c.methods = "shot,toldi"
    tasks.run(c, str(tmp_path / "whole"), progress=False)
    calls, real = [], methods.lrf

    def counting(name, *args, **kwargs):
        orient = real(name, *args, **kwargs)

        def run(fragment, indices):
            calls.append(name)
            if name == "toldi" and die:
                raise KeyboardInterrupt                      # the kill
            return orient(fragment, indices)
        return run

    monkeypatch.setattr(methods, "lrf", counting)
    die = True
    with pytest.raises(KeyboardInterrupt):
        tasks.run(c, str(tmp_path / "cut"), progress=False)
    assert "shot" in calls
    calls.clear()
    die = False
    tasks.run(c, str(tmp_path / "cut"), progress=False)
    assert calls and calls[0] == "toldi"                     # shot's first scene was kept
    assert _read_csv(tmp_path / "cut" / "lrf_results.csv") == \
        _read_csv(tmp_path / "whole" / "lrf_results.csv")
