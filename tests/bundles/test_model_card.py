"""Model cards and published tables are generated from the runs' own files: a trained bundle's
card states its command, steps, data and validation curve; an evaluation's run record, the
docs' section, the README's headline block and the cards' evaluation sections follow it."""
import csv
import json
import os
import shutil

import jax.numpy as jnp
import ml_collections
import pytest

from configs import eval_registration, lead
from experiments import publish, records, standing
from sphere_jax import training
from sphere_jax.models import shipped
from sphere_jax.bundles import model_card, store
from sphere_jax.eval import report, tasks

README = "# x\n\nabove\n\n<!-- headline:begin -->\nold\n<!-- headline:end -->\n\nbelow\n"


@pytest.mark.slow
def test_training_writes_the_card_and_evaluations_complete_it(tmp_path):
    c = lead.get_config("tiny")
    c.train.update(steps=2, log_every=1, eval_every=1, schedule="warmup_cosine",
                   warmup_steps=1, final_lr_fraction=0.1)
    training.train_and_evaluate(c, str(tmp_path / "w"), progress=False,
                                command="python -m experiments.train --config=lead:tiny")
    path = tmp_path / "w" / "bundle"
    card = (path / model_card.CARD).read_text()
    assert "python -m experiments.train --config=lead:tiny" in card
    assert "steps: 2 of 2 planned × batch 4" in card and "cosine decay to 0.1×" in card
    assert "synth-room-s1-0` (12 scans)" in card
    assert "evaluation scenes in the training data: none" in card
    # The validation table has one row per evaluated step, with the logged figures.
    logged = [json.loads(ln) for ln in (tmp_path / "w" / "metrics.jsonl").read_text().splitlines()]
    assert [ln["step"] for ln in logged] == [1, 2]
    assert f"| 2 | {logged[-1]['val_chamfer']:.4g} |" in card
    assert (path / model_card.CURVE).stat().st_size > 5000
    assert (path / model_card.METRICS).read_text() == (tmp_path / "w" / "metrics.jsonl").read_text()

    ev = eval_registration.get_config("tiny")
    ev.methods = "fpfh,lead"
    ev.bundles.lead = str(path)
    tasks.run(ev, str(tmp_path / "ev"), progress=False, command="python -m experiments.evaluate X")
    record = json.loads((tmp_path / "ev" / tasks.RUN_RECORD).read_text())
    assert record["command"] == "python -m experiments.evaluate X"
    assert list(record["bundles"]) == ["lead"] and record["bundles"]["lead"]["steps_done"] == 2

    outputs = _outputs(tmp_path, README, weights=tmp_path)    # the trained bundle: w/bundle
    readme = outputs.readme
    # The headline run alone: its section and the cards follow it, never another run of it.
    publish.publish([], headline=str(tmp_path / "ev"), root=str(tmp_path / "records"),
                    outputs=outputs)
    out = outputs.results
    with open(tmp_path / "ev" / "results.csv") as f:
        lead_mean = next(r for r in csv.DictReader(f) if r["method"] == "lead"
                         and r["scene"] == "mean")
    text = open(readme).read()
    assert "old" not in text and text.startswith("# x\n\nabove") and text.endswith("below\n")
    assert f"| lead | {float(lead_mean['fmr']):.2f} | {float(lead_mean['inlier_ratio']):.3f} |" \
        in text
    assert "`python -m experiments.evaluate X`" in open(out).read()
    card = (path / model_card.CARD).read_text()
    assert "## Evaluations" in card and "python -m experiments.evaluate X" in card


def _outputs(tmp_path, readme_text=README, weights=None) -> publish.Outputs:
    """Where a test's publish writes: a README holding ``readme_text``, results.md beside
    it, the cards of the bundles under ``weights`` (default ``tmp_path/weights``)."""
    repo = tmp_path / "repo"
    repo.mkdir(exist_ok=True)
    (repo / "README.md").write_text(readme_text)
    return publish.Outputs(results=str(repo / "results.md"), readme=str(repo / "README.md"),
                           registered=str(repo / "registered.md"),
                           performance=str(repo / "performance.md"),
                           weights=str(weights or tmp_path / "weights"))


def _publish(tmp_path, *args, **kwargs):
    if "outputs" not in kwargs:
        kwargs["outputs"] = _outputs(tmp_path)
    publish.publish(*args, root=str(tmp_path / "records"), **kwargs)
    return kwargs["outputs"]


def _compass_bundle(path, steps):
    store.save(path, ml_collections.ConfigDict({"model": "compass", "data": {"root": "x"},
                                                 "train": {"steps": steps, "batch_size": 1,
                                                           "learning_rate": 1e-3}}),
                {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    return path


def _shipped_compass(tmp_path, steps=1):
    """A compass bundle among the test's weights, and what a run records of it."""
    path = _compass_bundle(tmp_path / "weights" / "compass_x" / "bundle", steps)
    return path, {"path": str(path), "steps_done": steps, "fingerprint": store.fingerprint(path)}


def _lrf_run(tmp_path, name, root, recorded, means=None, title_steps=0):
    """An LRF run's folder: ``run.json`` naming the compass bundle as ``recorded``, and the
    mean rows of ``lrf_results.csv`` (``{method: (rep, mean angle)}``)."""
    run = tmp_path / f"run_{name}"
    run.mkdir(exist_ok=True)
    (run / "run.json").write_text(json.dumps({
        "command": f"evaluate {name}", "task": "lrf",
        "config": {"data": {"root": root}, "rho": 0.97, "adapt_steps": title_steps},
        "bundles": {"compass": recorded} if recorded else {}, "date": "2026-01-01",
        "wall_s": 60}))
    rows = [dict(method=m, scene=s, pairs=3, rep=rep, mean_angle_deg=angle)
            for m, (rep, angle) in (means or {"compass": (0.3, 80.0)}).items()
            for s in ("kitchen", "mean")]
    (run / "lrf_results.csv").write_text(report.to_csv(rows, report.LRF_COLUMNS))
    return str(run)


def _registration_run(tmp_path, name, bundles, means, methods=None):
    """A registration run's folder: ``run.json`` and ``results.csv`` (one scene and the mean
    rows, ``{method: (inlier ratio, correct, RR)}``)."""
    run = tmp_path / name
    run.mkdir()
    (run / "run.json").write_text(json.dumps({
        "command": f"evaluate {name}", "task": "registration", "bundles": bundles,
        "config": {"data": {"root": "/data/bunny", "radius": 0.3}, "tau1": 0.1, "tau2": 0.05,
                   "methods": methods or ",".join(means)},
        "date": "2026-01-01", "wall_s": 60}))
    rows = [dict(method=m, scene=s, pairs=4, fmr=1.0, inlier_ratio=ir, n_correct=n, rre_deg=1.0,
                 rte_m=0.01, ms_per_keypoint=1.0, others_cpu=0.0, rr=rr)
            for m, (ir, n, rr) in means.items() for s in ("bun", "mean")]
    (run / "results.csv").write_text(report.to_csv(rows, report.REGISTRATION_COLUMNS))
    return str(run)


def test_runs_of_one_task_on_two_data_sets_both_reach_the_card(tmp_path):
    """Two LRF runs share the table title; the card keeps both, named by their data."""
    path, recorded = _shipped_compass(tmp_path)
    runs = [_lrf_run(tmp_path, name, root, recorded)
            for name, root in (("a", "/data/kitchen"), ("b", "/data/bunny"))]
    _publish(tmp_path, runs)
    card = (path / model_card.CARD).read_text()
    assert "### LRF repeatability on /data/kitchen" in card
    assert "### LRF repeatability on /data/bunny" in card
    assert "| compass | 0.300 | 80.0 |" in card


def test_a_ground_truth_diagnostic_run_sits_beside_the_benchmark_on_the_card(tmp_path):
    """``lead_gt`` on the benchmark's data has the benchmark's title: its card entry is its
    own, and the benchmark's stays."""
    path, recorded = _shipped_compass(tmp_path)
    bench = _registration_run(tmp_path, "bench", {"compass": recorded},
                              {"lead": (0.2, 200, 1.0)}, methods="fpfh,lead")
    diag = _registration_run(tmp_path, "diag", {"compass": recorded},
                             {"lead_gt": (0.5, 400, 1.0)}, methods="lead,lead_gt")
    _publish(tmp_path, [bench, diag])
    card = (path / model_card.CARD).read_text()
    assert "evaluate bench" in card and "evaluate diag" in card
    assert "### Registration benchmark on /data/bunny, with ground-truth-frame diagnostics" in card


def test_a_card_lists_only_runs_of_its_own_bundle(tmp_path):
    """A run of an earlier version of the bundle (another fingerprint, or none recorded)
    stays out of the retrained bundle's card."""
    path, recorded = _shipped_compass(tmp_path, 5)
    runs = [_lrf_run(tmp_path, name, name, r) for name, r in (
        ("now", recorded), ("old", {**recorded, "fingerprint": "0" * 16}),
        ("older", {"path": str(path), "steps_done": 5}))]
    _publish(tmp_path, runs)
    card = (path / model_card.CARD).read_text()
    assert "LRF repeatability on now" in card
    assert "on old" not in card and "on older" not in card


def test_a_registration_section_is_one_table_with_its_pair_votes_below(tmp_path):
    """A run's section is one table of methods by metrics (means); a run with a pair vote
    says below it how far the votes' rotations were from the truth, a run without has none."""
    voted = _registration_run(tmp_path, "voted", {}, {"lead_vote": (0.5, 400, 1.0)})
    votes = [dict(method="lead_vote", scene="bun", pair=p, vote_rre_deg=e, vote_support=9,
                  vote_proposals=90, vote_mode=0, box_turn_deg=0.0, second_pass=kept)
             for p, e, kept in (("0-1", 1.5, True), ("0-2", 3.5, False), ("1-2", 2.0, True))]
    (tmp_path / "voted" / "votes.csv").write_text(report.to_csv(votes, list(votes[0])))
    plain = _registration_run(tmp_path, "plain", {}, {"shot": (0.3, 200, 1.0)})
    text = open(_publish(tmp_path, [voted, plain]).results).read()
    section = text[text.index("evaluate voted"):text.index("evaluate plain")]
    assert ("| method | FMR | inlier ratio | correct / pair | RR | RRE (°) | RTE (m) | "
            "ms / keypoint |") in section
    assert "| lead_vote | 1.000 | 0.500 | 400 | 1.00 | 1.00 | 0.010 | 1.00 |" in section
    votes_row = "| lead_vote | 3 | 2.00 | 3.50 | 2 |"
    assert section.index("| lead_vote | 1.000") < section.index(votes_row)
    assert text.count("voted method") == 1
    assert sorted(os.listdir(tmp_path / "records" / "voted")) == ["results.csv", "run.json",
                                                                  "votes.csv"]


def test_the_adaptation_record_compares_methods_and_names_the_adapted_bundle(tmp_path):
    shipped = _compass_bundle(tmp_path / "shipped", 100)
    adapted = tmp_path / "adapted"
    store.save(adapted, ml_collections.ConfigDict({
        "model": "compass", "data": {"root": "/scans/mine", "voxel": 0.001, "radius": 0.015},
        "train": {"steps": 1_000_000, "steps_done": 240, "time_budget_s": 600.0,
                  "best_step": 200, "batch_size": 2, "learning_rate": 1e-3}}),
        {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    # 240 steps of 2 patches at 4 patches per second: 2 minutes of steps.
    (adapted / model_card.METRICS).write_text(json.dumps({"step": 0, "val_loss": 1.0}) + "\n" +
                                              json.dumps({"step": 240, "patches_per_s": 4.0,
                                                          "loss": 0.5}) + "\n")
    before = _registration_run(tmp_path, "before", {"compass": {"path": str(shipped)}},
                               {"shot": (0.06, 23, 0.4), "lead_compass": (0.08, 55, 0.6)})
    after = _registration_run(tmp_path, "after", {"compass": {"path": str(adapted)}},
                              {"lead_compass": (0.10, 70, 0.7)})
    text = publish.comparison_section(publish.comparison(before, after))
    assert "| lead_compass | 0.080 | 0.100 | +25% | 55 | 70 | 0.60 | 0.70 |" in text
    assert "| shot | 0.060 | – | – | 23 | – | 0.40 | – |" in text
    assert ("compass: 240 steps, 2.0 min of them (budget 10), weights of step 200, on "
            "`/scans/mine` at voxel 0.001, radius 0.015") in text
    assert "Before: `evaluate before`" in text and "After: `evaluate after`" in text
    assert text.startswith("## Adaptation without labels, compass adapted, 10 min: ")
    # Its record outlives the adapted bundle and both workdirs.
    _publish(tmp_path, adaptations=[(before, after)])
    for gone in (adapted, tmp_path / "before", tmp_path / "after"):
        shutil.rmtree(gone)
    outputs = _outputs(tmp_path)
    rendered = publish.render(str(tmp_path / "records"), outputs)
    assert text.strip() in rendered[outputs.results]


def test_an_adaptation_title_names_the_budgets(tmp_path):
    """Two adaptations of the same networks differ by their minutes: the title says them."""
    saved = {}
    for kind, budget_s in (("compass", 600.0), ("lead", 300.0), ("sound", 0.0)):
        saved[kind] = tmp_path / kind
        store.save(saved[kind], ml_collections.ConfigDict({
            "model": kind, "data": {"root": "x"},
            "train": {"steps": 500, "time_budget_s": budget_s, "batch_size": 2}}),
            {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    pick = lambda *kinds: {k: str(saved[k]) for k in kinds}
    assert publish.budgets(pick("compass")) == ", 10 min"
    assert publish.budgets(pick("compass", "lead")) == ", compass 10 min, lead 5 min"
    assert publish.budgets(pick("sound")) == ""
    assert publish.budgets(pick("lead", "sound")) == ", lead 5 min, sound by steps"


def test_a_minutes_budget_card_has_no_step_total_and_names_the_constant_rate(tmp_path):
    path = tmp_path / "adapted"
    store.save(path, ml_collections.ConfigDict({
        "model": "compass", "data": {"root": "x"},
        "train": {"steps": 1_000_000, "steps_done": 40, "time_budget_s": 300.0,
                  "budget_ends": True, "schedule": "warmup_cosine", "warmup_steps": 25,
                  "final_lr_fraction": 1.0, "batch_size": 2, "learning_rate": 1e-4}}),
        {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    card = open(model_card.render(path)).read()
    assert "- steps: 40 within a 5-minute budget × batch 2; learning rate 0.0001 after 25 " \
           "warm-up steps, then constant (Adam)" in card
    assert "1000000" not in card


def _csv_run(tmp_path, name, stem, header, means):
    """A run folder with mean rows of ``<stem>.csv`` only: what standing reads."""
    run = tmp_path / name
    run.mkdir()
    with open(run / f"{stem}.csv", "w") as f:
        f.write(header + "\n" + "".join(f"{m},mean,{v}\n" for m, v in means.items()))
    return str(run)


def test_the_targets_table_says_what_is_met_and_by_how_much(tmp_path):
    """The README's targets block, from five runs' mean rows: the best learned descriptor is
    the one with the highest 3DMatch inlier ratio, each target measured against its runs."""
    reg = "method,scene,fmr,inlier_ratio,n_correct,rr"
    match = _csv_run(tmp_path, "match", "results", reg, {
        "shot": "1,0.30,200,1", "usc": "1,0.40,210,1", "lead": "1,0.20,250,1",
        "lead_pn": "0.9,0.35,320,1", "lead_vote": "1,0.60,400,1"})
    lomatch = _csv_run(tmp_path, "lo", "results", reg, {
        "shot": "0.5,0.05,30,0.4", "usc": "0.5,0.08,35,0.7", "lead_pn": "0.5,0.06,45,0.6",
        "lead_vote": "0.5,0.10,50,0.5"})
    rotated = _csv_run(tmp_path, "rot", "results", reg, {"lead_pn": "1,0.28,300,1"})
    lrf = "method,scene,rep"
    kitchen = _csv_run(tmp_path, "k", "lrf_results", lrf, {"flare": "0.20", "compass": "0.25"})
    bunny = _csv_run(tmp_path, "b", "lrf_results", lrf, {"flare": "0.40", "compass": "0.20"})
    text = standing.table(match, lomatch, rotated, kitchen, bunny)
    assert ("| best learned descriptor (lead_pn): inlier ratio ≥ 1.15× USC's and ≥ 1.3× SHOT's "
            "| 0.350 against 0.400 and 0.300 (0.87× and 1.17×) | **no** |") in text
    assert "| its correct matches per pair ≥ 2× SHOT's | 320 against 200 (1.60×) | **no** |" in text
    assert "| its feature-match recall ≥ 0.95 | 0.900 | **no** |" in text
    assert ("| its inlier ratio, every scan rotated: within 5 % | 0.280 (-20.0 %) | **no** |"
            in text)
    assert "| 3DLoMatch: its registration recall ≥ USC's | 0.600 against 0.700 | **no** |" in text
    assert "| 2.00× and 2.00× | yes |" in text
    assert "on redkitchen, without adaptation | 0.250 against 0.200 (1.25×) | **no** |" in text
    assert "on the bunny, without adaptation | 0.200 against 0.400 (0.50×) | **no** |" in text


def test_the_targets_block_follows_its_records(tmp_path):
    """``--targets`` records its five runs and fills the README's block from the records."""
    means = {"shot": (0.30, 200, 1.0), "usc": (0.40, 210, 1.0), "lead_pn": (0.35, 320, 1.0)}
    runs = [_registration_run(tmp_path, n, {}, means) for n in ("m", "lo", "rot")]
    runs += [_lrf_run(tmp_path, n, "/d", {}, {"flare": (0.2, 80.0), "compass": (0.25, 70.0)})
             for n in ("k", "b")]
    outputs = _outputs(tmp_path, "a\n<!-- targets:begin -->\nold\n<!-- targets:end -->\nb\n")
    _publish(tmp_path, targets=runs, outputs=outputs)
    text = open(outputs.readme).read()
    assert "old" not in text and text.startswith("a\n") and text.endswith("b\n")
    assert "| its correct matches per pair ≥ 2× SHOT's | 320 against 200 (1.60×) | **no** |" in text
    assert "From the records m, lo, rot, run_k, run_b" in text
    assert records.read_index(str(tmp_path / "records"))["targets"] == ["m", "lo", "rot",
                                                                       "run_k", "run_b"]


def test_publishing_a_run_again_replaces_only_its_own_section(tmp_path):
    """docs/results.md keeps one section per record: a rerun's publish replaces its record
    and section in place and leaves the others (their workdirs may be long gone); ``fresh``
    keeps only the runs given; ``drop`` removes a record with its section."""
    a, b = (_lrf_run(tmp_path, name, f"/data/{name}", {}) for name in ("a", "b"))
    outputs = _publish(tmp_path, [a, b])
    _lrf_run(tmp_path, "a", "/data/a", {}, {"compass": (0.5, 10.0)})
    _publish(tmp_path, [a], outputs=outputs)
    text = open(outputs.results).read()
    assert "| compass | 0.500 | 10.0 |" in text and "| compass | 0.300 | 80.0 |" in text
    assert text.index("/data/a") < text.index("/data/b")            # in its place
    assert text.count("<!-- section:") == 2
    shutil.rmtree(b)
    _publish(tmp_path, drop=["run_a"], outputs=outputs)
    assert "/data/a" not in open(outputs.results).read()
    assert "/data/b" in open(outputs.results).read()
    assert not (tmp_path / "records" / "run_a").exists()
    with pytest.raises(ValueError, match="--drop: no record 'run_a'"):
        _publish(tmp_path, drop=["run_a"], outputs=outputs)
    _publish(tmp_path, [a], fresh=True, outputs=outputs)
    assert "/data/b" not in open(outputs.results).read()


def test_a_new_comparison_joins_the_others(tmp_path):
    """A new before/after comparison goes after the last one, where a reader finds them."""
    runs = {n: _lrf_run(tmp_path, n, f"/d/{n}", {}) for n in ("a", "b", "x", "y")}
    outputs = _publish(tmp_path, [runs["a"]], adaptations=[(runs["a"], runs["x"])])
    _publish(tmp_path, [runs["b"]], outputs=outputs)
    _publish(tmp_path, adaptations=[(runs["b"], runs["y"])], outputs=outputs)
    assert records.read_index(str(tmp_path / "records"))["sections"] == [
        "run_a", "adaptation-run_x", "adaptation-run_y", "run_b"]


def test_the_contents_link_each_section_by_its_github_anchor():
    sections = [("a", "## Registration benchmark on ../shared/data/x-y, ground truth z\n\n|"),
                ("b", "no title"), ("c", "## LRF repeatability on d"),
                ("e", "## LRF repeatability on d")]
    assert publish.contents(sections) == [
        "- [Registration benchmark on ../shared/data/x-y, ground truth z]"
        "(#registration-benchmark-on-shareddatax-y-ground-truth-z)",
        "- [LRF repeatability on d](#lrf-repeatability-on-d)",
        "- [LRF repeatability on d](#lrf-repeatability-on-d-1)"]


def test_an_lrf_adaptation_section_names_the_bundle_the_run_adapted_itself(tmp_path):
    """An LRF run with test-time adaptation records the shipped bundle; the one it adapted
    lies in its folder (``adapted_compass/bundle``): the section compares repeatability and
    names that one."""
    shipped = _compass_bundle(tmp_path / "shipped", 100)
    recorded = {"path": str(shipped), "steps_done": 100}
    before = _lrf_run(tmp_path, "before", "/data/bunny", recorded,
                      {"flare": (0.4, 60.0), "compass": (0.2, 90.0)})
    after = _lrf_run(tmp_path, "after", "/data/bunny", recorded,
                     {"flare": (0.4, 60.0), "compass": (0.3, 70.5)}, title_steps=50)
    adapted = tmp_path / "run_after" / "adapted_compass" / "bundle"
    store.save(adapted, ml_collections.ConfigDict({
        "model": "compass", "data": {"root": "/data/bunny", "voxel": 0.001, "radius": 0.015},
        "train": {"steps": 50, "steps_done": 50, "best_step": 50, "batch_size": 2,
                  "learning_rate": 1e-4}}), {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    text = publish.comparison_section(publish.comparison(before, after))
    assert "## Adaptation without labels, compass adapted: LRF repeatability on " \
           "/data/bunny" in text
    assert "| method | repeatability: before | after | change | mean angle (degrees): " \
           "before | after |" in text
    assert "| compass | 0.200 | 0.300 | +50% | 90.0 | 70.5 |" in text
    assert "| flare | 0.400 | 0.400 | +0% | 60.0 | 60.0 |" in text
    assert "compass: 50 steps" in text and f"(`{adapted}`)" in text
    with pytest.raises(ValueError, match="two runs of one task"):
        publish.comparison(before, _registration_run(tmp_path, "reg", {}, {}))


def test_a_compass_target_shows_the_declared_adaptation_but_counts_without_it(tmp_path):
    """With the LRF runs that adapted Compass on the scans first, the Compass rows show both
    figures; only the shipped bundle's own can meet the target."""
    reg = "method,scene,fmr,inlier_ratio,n_correct,rr"
    means = {"shot": "1,0.30,200,1", "usc": "1,0.40,210,1", "lead_pn": "1,0.35,320,1"}
    runs = [_csv_run(tmp_path, name, "results", reg, means) for name in ("m", "lo", "rot")]
    lrf = "method,scene,rep"
    for name, compass in (("k", "0.21"), ("b", "0.20"), ("ka", "0.22"), ("ba", "0.44")):
        runs.append(_csv_run(tmp_path, name, "lrf_results", lrf,
                             {"flare": "0.20" if name.startswith("k") else "0.40",
                              "compass": compass}))
    rows = {t: (v, ok) for t, v, ok in standing.rows(*runs[:5], None, *runs[5:])}
    kitchen = rows["Compass: LRF repeatability ≥ 1.5× FLARE's on redkitchen, without adaptation"]
    assert kitchen == ("0.210 against 0.200 (1.05×); adapted on the scans first: 0.220 (1.10×)",
                       False)
    bunny = rows["Compass: LRF repeatability ≥ 1× FLARE's on the bunny, without adaptation"]
    assert bunny == ("0.200 against 0.400 (0.50×); adapted on the scans first: 0.440 (1.10×)",
                     False)
    best = rows["best learned descriptor (lead_pn): inlier ratio ≥ 1.15× USC's and ≥ 1.3× SHOT's"]
    assert best == ("0.350 against 0.400 and 0.300 (0.87× and 1.17×)", False)
    assert rows["its correct matches per pair ≥ 2× SHOT's"] == ("320 against 200 (1.60×)", False)


def test_a_rerun_in_the_same_workdir_replaces_its_card_entry(tmp_path):
    """A card entry is its record's: rerun in the same workdir on data that moved, the run
    replaces its old entry instead of standing beside it."""
    path, recorded = _shipped_compass(tmp_path)
    outputs = _publish(tmp_path, [_lrf_run(tmp_path, "lrf", "/old/place", recorded)])
    _publish(tmp_path, [_lrf_run(tmp_path, "lrf", "runs/new_place", recorded)], outputs=outputs)
    card = (path / model_card.CARD).read_text()
    assert "on runs/new_place" in card and "/old/place" not in card


def test_a_stamp_names_which_weights_and_whether_results_were_reused():
    record = {"command": "python -m experiments.evaluate --config=eval_lrf", "task": "lrf",
              "config": {"data": {"root": "scans"}}, "date": "2026-01-02", "wall_s": 120.0,
              "bundles": {"compass": {"path": "w/bundle", "steps_done": 60,
                                      "fingerprint": "0123456789abcdef"}}}
    line = publish.stamp(record)
    assert "compass `w/bundle` (60 steps, fingerprint 0123456789abcdef)" in line
    assert line.endswith("Run 2026-01-02, 2 min.")
    record["resumed"] = True
    assert "reusing the results an earlier run of it kept, the rest in 2 min" in \
        publish.stamp(record)


def test_the_headline_marks_a_time_measured_beside_other_processes(tmp_path):
    rows = [dict(method="fpfh", scene="mean", pairs=4, fmr=0.5, inlier_ratio=0.1, n_correct=20,
                 rre_deg=1.0, rte_m=0.01, ms_per_keypoint=0.05, others_cpu=0.02, rr=0.5),
            dict(method="lead", scene="mean", pairs=4, fmr=0.75, inlier_ratio=0.2,
                 n_correct=40, rre_deg=1.0, rte_m=0.01, ms_per_keypoint=4.5, others_cpu=0.46,
                 rr=0.75),
            dict(method="shot", scene="mean", pairs=4, fmr=0.75, inlier_ratio=0.2,
                 n_correct=40, rre_deg=1.0, rte_m=0.01, ms_per_keypoint=0.3,
                 others_cpu=float("nan"), rr=0.75)]
    (tmp_path / "results.csv").write_text(report.to_csv(rows, report.REGISTRATION_COLUMNS))
    table = publish.headline_table(str(tmp_path))
    assert "| lead | 0.75 | 0.200 | 40 | 0.75 | 4.50 (shared 46%) |" in table
    assert "| fpfh | 0.50 | 0.100 | 20 | 0.50 | 0.05 |" in table        # alone
    assert "| shot | 0.75 | 0.200 | 40 | 0.75 | 0.30 |" in table        # not recorded
    assert "other processes used N % of the cores" in table


def test_the_weights_index_names_each_bundles_data_root_and_scan_count(tmp_path):
    """One row per shipped kind: its config's data.root as given and the scans (or shapes)
    it held, summed over the training statement's folders."""
    for folder, root, data in (
            ("c", "embedded:1,shared/x", {"kind": "scans", "folders": {"a": 12, "b": 1}}),
            ("s", "/shapes", {"kind": "shapes", "folders": {"/shapes": 1}})):
        store.save(tmp_path / folder / "bundle", ml_collections.ConfigDict({
            "model": "compass", "data": {"root": root},
            "train": {"steps": 3, "batch_size": 2, "learning_rate": 1e-3}}),
            {"params": {"w": jnp.ones(1)}, "batch_stats": {}}, training_data=data)
    rows = {"compass": shipped.Shipped("c", "compass", "compass"),
            "compass_shapes": shipped.Shipped("s", "compass", "compass_shapes")}
    index = open(model_card.weights_index(str(tmp_path), rows)).read()
    assert "| 3 / 3 × 2 | `embedded:1,shared/x` (13 scans) |" in index
    assert "| `/shapes` (1 shape) |" in index


def test_classification_targets_fill_their_readme_block(tmp_path):
    run = tmp_path / "cls"
    run.mkdir()
    rows = [dict(method=m, split=s, accuracy=a, thesis=0.0) for m, s, a in (
        ("pointnet", "NR", 0.86), ("pointnet", "AR", 0.12), ("compass+pointnet", "NR", 0.80),
        ("compass+pointnet", "AR", 0.70))]
    (run / "classification.csv").write_text(report.to_csv(rows, list(rows[0])))
    (run / "run.json").write_text(json.dumps({"wall_s": 420.0}))
    got = {t: (v, ok) for t, v, ok in standing.classification_rows(str(run))}
    assert got["Compass + PointNet: AR accuracy ≥ 0.72 (the thesis's 72.2 %)"] == ("0.700", False)
    assert got["Compass + PointNet: AR within 0.08 of its NR"] == (
        "0.700 against 0.800 (-0.100)", False)
    assert got["plain PointNet: NR accuracy ≥ 0.85 (its AR reported)"] == (
        "0.860 (AR 0.120)", True)
    assert got["evaluating the shipped classifiers, NR and AR: ≤ 10 minutes on 2 cores"][1]
    outputs = _outputs(tmp_path, "a\n<!-- classification-targets:begin -->\nold\n"
                                 "<!-- classification-targets:end -->\nb\n")
    (run / "training.csv").write_text("method,steps,batch,train_min\npointnet,10,2,1.5\n")
    (run / "classification.json").write_text(json.dumps({"test_shapes": 9, "rule": "r"}))
    (run / "run.json").write_text(json.dumps({"wall_s": 420.0, "task": "classification",
                                              "config": {"data": {"root": "/s"}},
                                              "date": "2026-01-01", "command": "c"}))
    _publish(tmp_path, classification=str(run), outputs=outputs)
    text = open(outputs.readme).read()
    assert "| Compass + PointNet: AR accuracy ≥ 0.72 (the thesis's 72.2 %) | 0.700 | **no** |" \
        in text and "old" not in text and text.endswith("end -->\nb\n")


def test_the_frame_target_holds_lead_in_compass_frames_against_the_ground_truth(tmp_path):
    """LEAD in Compass's frames keeps ≥ 75 % of its inlier ratio in ground-truth frames: read
    from the run that describes both with one whitening and one draw of keypoints."""
    reg = "method,scene,fmr,inlier_ratio,n_correct,rr"
    means = {"shot": "1,0.30,200,1", "usc": "1,0.40,210,1", "lead_pn": "1,0.35,320,1"}
    runs = [_csv_run(tmp_path, name, "results", reg, means) for name in ("m", "lo", "rot")]
    runs += [_csv_run(tmp_path, name, "lrf_results", "method,scene,rep",
                      {"flare": "0.20", "compass": "0.25"}) for name in ("k", "b")]
    target = ("LEAD in Compass's frames: ≥ 75 % of its inlier ratio in the ground-truth frames "
              "(same whitening and keypoints)")
    for compass, expected in (("0.30", ("0.300 against 0.500 (60%)", False)),
                              ("0.40", ("0.400 against 0.500 (80%)", True))):
        gt = _csv_run(tmp_path, f"gt{compass}", "results", reg,
                      {"lead_compass": f"1,{compass},300,1", "lead_gt": "1,0.50,400,1"})
        assert {t: (v, ok) for t, v, ok in standing.rows(*runs, gt)}[target] == expected


def test_registered_runs_have_a_page_of_their_own(tmp_path):
    """An experiments.registered workdir's record renders in docs/registered.md: its commands,
    the statuses under the thresholds it ran with and, after --fit, under the fitted ones."""
    from sphere_jax.eval import registered
    run = tmp_path / "registered_x"
    run.mkdir()
    rows = [dict(set="s", i=0, j=k, method="shot", status=st, right=ok, inliers=n, rival=5,
                 matches=100, fitness=0.5, rre_deg=1.0, rte=0.01, radius=0.3, seconds=1.0)
            for k, (st, ok, n) in enumerate((("registered", 1, 60), ("registered", 0, 45),
                                             ("unconfirmed", 1, 20), ("failed", 0, 0)))]
    (run / "registered.csv").write_text(report.to_csv(rows, registered.FIELDS))
    (run / "run.json").write_text(json.dumps({
        "task": "registered", "date": "2026-01-01", "commands": ["reg a", "reg b"],
        "data": ["/d"], "methods": ["shot"], "thresholds": {"min_inliers": 40, "margin": 2.0}}))
    (run / "fit.json").write_text(json.dumps({"min_inliers": 50, "margin": 2.0,
                                              "right_kept": 0.5}))
    outputs = _publish(tmp_path, registered=[str(run)])
    text = open(outputs.registered).read()
    assert text.startswith(registered.PAGE) and "## /d" in text
    assert "`reg a`\n\nthen\n\n`reg b`" in text
    assert "| shot | 4 | 1 | 1 | 0 | 1 | 0 | 1 |" in text            # 40 inliers: 45 passes
    assert "| shot | 4 | 1 | 1 | 0 | 0 | 1 | 1 |" in text            # fitted 50: it does not
    assert records.read_index(str(tmp_path / "records"))["registered"] == ["registered_x"]


def test_a_benchmark_record_fills_its_block_of_the_performance_page(tmp_path):
    """``experiments.bench --record=DIR`` writes bench.json; publishing it fills the suite's
    block of docs/performance.md with its table and where it ran, the prose around it kept."""
    run = tmp_path / "b"
    run.mkdir()
    (run / "bench.json").write_text(json.dumps({
        "suite": "describe", "command": "python -m experiments.bench --suite=describe",
        "machine": "x86_64, 2 CPU cores", "date": "2026-01-01",
        "records": [{"method": "lead", "ms_per_keypoint": 1.5, "gflop": None,
                     "register_stages": {"ICP": 0.25}}]}))
    outputs = _outputs(tmp_path)
    with open(outputs.performance, "w") as f:
        f.write("above\n<!-- bench-describe:begin -->\nold\n<!-- bench-describe:end -->\nbelow\n")
    _publish(tmp_path, bench=[str(run)], outputs=outputs)
    text = open(outputs.performance).read()
    assert text.startswith("above\n") and text.endswith("below\n") and "old" not in text
    assert "| lead   | 1.5             |       |" in text               # None: empty
    assert "`register_stages`:\n\n| method | ICP  |" in text and "| lead   | 0.25 |" in text
    assert "`python -m experiments.bench --suite=describe` on x86_64, 2 CPU cores, 2026-01-01" \
        in text
