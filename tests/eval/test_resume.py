"""Kept evaluation results follow the bundles each method uses: retraining LEAD redoes the
LEAD methods and keeps the hand-crafted ones; a copy of a bundle elsewhere (another checkout)
keeps them all."""
import collections
import shutil

import ml_collections

from sphere_jax.eval import resume

Result = collections.namedtuple("Result", "method scene value")


def _bundle(folder, weights):
    (folder / "variables").mkdir(parents=True)
    (folder / "config.json").write_text('{"model": "lead"}')
    (folder / "variables" / "w.bin").write_bytes(weights)
    return str(folder)


def _kept(tmp_path, bundles):
    config = ml_collections.ConfigDict({"seed": 0, "methods": "fpfh,lead", "bundles": bundles})
    finished = resume.Finished(tmp_path / "run", config, bundles)
    return {m: finished.get(m, "kitchen") for m in ("fpfh", "lead", "lead_compass")}, finished


def test_kept_results_follow_the_bundles_each_method_uses(tmp_path):
    bundles = {"lead": _bundle(tmp_path / "lead", b"1"),
               "compass": _bundle(tmp_path / "compass", b"c")}
    _, finished = _kept(tmp_path, bundles)
    for m in ("fpfh", "lead", "lead_compass"):
        finished.put(Result(m, "kitchen", 1.0))
    moved = {k: shutil.copytree(p, tmp_path / "elsewhere" / k) for k, p in bundles.items()}
    kept, _ = _kept(tmp_path, {k: str(p) for k, p in moved.items()})    # same files: all kept
    assert all(r is not None and r.value == 1.0 for r in kept.values())
    (moved["lead"] / "variables" / "w.bin").write_bytes(b"2")            # LEAD retrained
    config = ml_collections.ConfigDict({"seed": 0, "methods": "lead", "bundles": {}})
    assert resume.kept(tmp_path / "run", config, {k: str(p) for k, p in moved.items()}) == 1
    assert resume.kept(tmp_path / "run", config, {}) == 1                # fpfh needs none
    config.seed = 1                                                      # another config
    assert resume.kept(tmp_path / "run", config, {k: str(p) for k, p in moved.items()}) == 0
    kept, _ = _kept(tmp_path, {k: str(p) for k, p in moved.items()})
    assert kept["fpfh"] is not None
    assert kept["lead"] is None and kept["lead_compass"] is None


def test_a_new_way_of_drawing_supports_redoes_the_networks_and_flare(tmp_path, monkeypatch):
    """Results of methods that read resampled supports (the networks, FLARE's frames) are kept
    under the support draw too; the hand-crafted descriptors' are not."""
    bundles = {"lead": _bundle(tmp_path / "lead", b"1")}
    config = ml_collections.ConfigDict({"seed": 0, "methods": "fpfh,lead", "bundles": {}})
    finished = resume.Finished(tmp_path / "run", config, bundles)
    for m in ("fpfh", "shot", "lead", "flare"):
        finished.put(Result(m, "kitchen", 1.0))
    assert resume.kept(tmp_path / "run", config, bundles) == 4
    monkeypatch.setattr(resume.supports, "DRAW", "random")
    after = resume.Finished(tmp_path / "run", config, bundles)
    assert {m for m in ("fpfh", "shot", "lead", "flare")
            if after.get(m, "kitchen") is not None} == {"fpfh", "shot"}
