"""Model cards and published tables are generated from the runs' own files: a trained bundle's
card states its command, steps, data and validation curve; an evaluation's run record, the
docs' section, the README's headline block and the cards' evaluation sections follow it."""
import csv
import json
import os

import jax.numpy as jnp
import ml_collections
import pytest

from configs import eval_registration, lead
from experiments import publish, standing
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

    readme = tmp_path / "README.md"
    readme.write_text(README)
    # The headline run alone: its section and the cards follow it, never another run of it.
    out = publish.publish([], headline=str(tmp_path / "ev"),
                          results=str(tmp_path / "docs" / "results.md"), readme=str(readme))
    with open(tmp_path / "ev" / "results.csv") as f:
        lead_mean = next(r for r in csv.DictReader(f) if r["method"] == "lead"
                         and r["scene"] == "mean")
    text = readme.read_text()
    assert "old" not in text and text.startswith("# x\n\nabove") and text.endswith("below\n")
    assert f"| lead | {float(lead_mean['fmr']):.2f} | {float(lead_mean['inlier_ratio']):.3f} |" \
        in text
    assert "`python -m experiments.evaluate X`" in open(out).read()
    card = (path / model_card.CARD).read_text()
    assert "## Evaluations" in card and "python -m experiments.evaluate X" in card


def _compass_bundle(path, steps):
    store.save(path, ml_collections.ConfigDict({"model": "compass", "data": {"root": "x"},
                                                 "train": {"steps": steps, "batch_size": 1,
                                                           "learning_rate": 1e-3}}),
                {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    return path


def _lrf_run(tmp_path, name, root, recorded):
    """An LRF run's folder (``run.json`` naming the compass bundle as ``recorded``)."""
    run = tmp_path / f"run_{name}"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({
        "command": f"evaluate {name}", "task": "lrf", "config": {"data": {"root": root}},
        "bundles": {"compass": recorded}, "date": "2026-01-01", "wall_s": 60}))
    (run / "lrf_results.md").write_text(f"# LRF repeatability\n\n| {name} |\n")
    return str(run)


def test_runs_of_one_task_on_two_data_sets_both_reach_the_card(tmp_path):
    """Two LRF runs share the table title; the card keeps both, named by their data."""
    path = _compass_bundle(tmp_path / "bundle", 1)
    runs = [_lrf_run(tmp_path, name, root, {"path": str(path), "steps_done": 1})
            for name, root in (("a", "/data/kitchen"), ("b", "/data/bunny"))]
    publish.publish(runs, results=str(tmp_path / "results.md"))
    card = (path / model_card.CARD).read_text()
    assert "### LRF repeatability on /data/kitchen" in card
    assert "### LRF repeatability on /data/bunny" in card


def test_a_ground_truth_diagnostic_run_sits_beside_the_benchmark_on_the_card(tmp_path):
    """``lead_gt`` on the benchmark's data has the benchmark's title: its card entry is its
    own, and the benchmark's stays."""
    path = _compass_bundle(tmp_path / "bundle", 1)
    recorded = {"compass": {"path": str(path), "steps_done": 1}}
    bench = _registration_run(tmp_path, "bench", recorded, {"lead": (0.2, 200, 1.0)})
    diag = _registration_run(tmp_path, "diag", recorded, {"lead_gt": (0.5, 400, 1.0)})
    for run, methods in ((bench, "fpfh,lead"), (diag, "lead,lead_gt")):
        record = json.loads(open(os.path.join(run, "run.json")).read())
        record["config"]["methods"] = methods
        open(os.path.join(run, "run.json"), "w").write(json.dumps(record))
    publish.publish([bench, diag], results=str(tmp_path / "results.md"))
    card = (path / model_card.CARD).read_text()
    assert "evaluate bench" in card and "evaluate diag" in card
    assert "### Registration benchmark on /data/bunny, with ground-truth-frame diagnostics" in card


def test_a_card_lists_only_runs_of_its_own_bundle(tmp_path):
    """A run of an earlier version of the bundle (another fingerprint, or other steps where
    none was recorded) stays out of the retrained bundle's card."""
    path = _compass_bundle(tmp_path / "bundle", 5)
    runs = [_lrf_run(tmp_path, name, name, {"path": str(path), **recorded}) for name, recorded in (
        ("now", {"fingerprint": store.fingerprint(path), "steps_done": 5}),
        ("old", {"fingerprint": "0" * 16, "steps_done": 5}), ("older", {"steps_done": 3}))]
    publish.publish(runs, results=str(tmp_path / "results.md"))
    card = (path / model_card.CARD).read_text()
    assert "LRF repeatability on now" in card
    assert "on old" not in card and "on older" not in card


def _registration_run(tmp_path, name, bundles, means):
    """A registration run's folder: ``run.json`` and the mean rows of ``results.csv``."""
    run = tmp_path / name
    run.mkdir()
    (run / "run.json").write_text(json.dumps({
        "command": f"evaluate {name}", "task": "registration", "bundles": bundles,
        "config": {"data": {"root": "/data/bunny"}}, "date": "2026-01-01", "wall_s": 60}))
    (run / "results.md").write_text("# Registration benchmark\n")
    with open(run / "results.csv", "w") as f:
        f.write("method,scene,inlier_ratio,n_correct,rr\n")
        for method, (ir, n, rr) in means.items():
            f.write(f"{method},bun,0,0,0\n{method},mean,{ir},{n},{rr}\n")
    return str(run)


def test_a_registration_section_shows_its_pair_votes_below_its_tables(tmp_path):
    """The vote's rotation errors (votes.md) are published in the run's section, after its
    own tables; a run without a vote has none."""
    voted = _registration_run(tmp_path, "voted", {}, {"lead_vote": (0.5, 400, 1.0)})
    (tmp_path / "voted" / "results.md").write_text("# Registration benchmark\n\n| ir |\n")
    (tmp_path / "voted" / "votes.md").write_text("# Pair votes\n\n| lead_vote | 0-4 | 1.42 |\n")
    plain = _registration_run(tmp_path, "plain", {}, {"shot": (0.3, 200, 1.0)})
    results = tmp_path / "results.md"
    publish.publish([voted, plain], results=str(results))
    text = results.read_text()
    section = text[text.index("evaluate voted"):text.index("evaluate plain")]
    assert section.index("| ir |") < section.index("### Pair votes") < section.index(
        "| lead_vote | 0-4 | 1.42 |")
    assert text.count("Pair votes") == 1


def test_the_adaptation_section_compares_methods_and_names_the_adapted_bundle(tmp_path):
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
    text = publish.adaptation_section(before, after)
    assert "| lead_compass | 0.080 | 0.100 | +25% | 55 | 70 | 0.60 | 0.70 |" in text
    assert "| shot | 0.060 | – | – | 23 | – | 0.40 | – |" in text
    assert ("compass: 240 steps, 2.0 min of them (budget 10), weights of step 200, on "
            "`/scans/mine` at voxel 0.001, radius 0.015") in text
    assert "Before: `evaluate before`" in text and "After: `evaluate after`" in text
    assert text.startswith("## Adaptation without labels, compass adapted, 10 min: ")


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
    readme = tmp_path / "README.md"
    readme.write_text("a\n<!-- targets:begin -->\nold\n<!-- targets:end -->\nb\n")
    publish.publish([], results=str(tmp_path / "results.md"), readme=str(readme),
                    targets=[match, lomatch, rotated, kitchen, bunny])
    text = readme.read_text()
    assert "old" not in text and text.startswith("a\n") and text.endswith("b\n")
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


def test_publishing_a_run_again_replaces_only_its_own_section(tmp_path):
    """docs/results.md keeps one section per run folder: a rerun's publish replaces its
    section in place and leaves the others (their folders may be long gone); ``fresh`` writes
    only the runs given; ``drop`` removes a section by its key."""
    path = _compass_bundle(tmp_path / "bundle", 1)
    recorded = {"path": str(path), "steps_done": 1}
    a, b = (_lrf_run(tmp_path, name, f"/data/{name}", recorded) for name in ("a", "b"))
    results = str(tmp_path / "results.md")
    publish.publish([a, b], results=results)
    (tmp_path / "run_a" / "lrf_results.md").write_text("# LRF repeatability\n\n| a again |\n")
    publish.publish([a], results=results)
    text = open(results).read()
    assert "| a again |" in text and "| a |" not in text and "| b |" in text
    assert text.index("/data/a") < text.index("/data/b")            # in its place
    assert text.count("<!-- section:") == 2
    key = publish.run_key(a)
    publish.publish([], results=results, drop=[key])
    assert "/data/a" not in open(results).read() and "| b |" in open(results).read()
    with pytest.raises(ValueError, match=f"--drop: no section '{key}'"):
        publish.publish([], results=results, drop=[key])
    publish.publish([a], results=results, fresh=True)
    assert "/data/b" not in open(results).read()


def test_a_new_adaptation_section_joins_the_others():
    old = "".join(f"<!-- section: {k} -->\n{k} text\n\n" for k in
                  ("runs/a", "adaptation runs/a2", "runs/b"))
    got = publish.merged_sections(old, [("adaptation runs/b2", "new"), ("runs/c", "c"),
                                        ("runs/a", "a again")])
    assert [k for k, _ in got] == ["runs/a", "adaptation runs/a2", "adaptation runs/b2",
                                   "runs/b", "runs/c"]
    assert dict(got)["runs/a"] == "a again"


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
    lrf = "method,scene,rep,mean_angle_deg"
    before = _lrf_run(tmp_path, "before", "/data/bunny", recorded)
    after = _lrf_run(tmp_path, "after", "/data/bunny", recorded)
    for run, means in ((before, {"flare": "0.400,60.0", "compass": "0.200,90.0"}),
                       (after, {"flare": "0.400,60.0", "compass": "0.300,70.5"})):
        with open(f"{run}/lrf_results.csv", "w") as f:
            f.write(lrf + "\n" + "".join(f"{m},mean,{v}\n" for m, v in means.items()))
    adapted = tmp_path / "run_after" / "adapted_compass" / "bundle"
    store.save(adapted, ml_collections.ConfigDict({
        "model": "compass", "data": {"root": "/data/bunny", "voxel": 0.001, "radius": 0.015},
        "train": {"steps": 50, "steps_done": 50, "best_step": 50, "batch_size": 2,
                  "learning_rate": 1e-4}}), {"params": {"w": jnp.ones(1)}, "batch_stats": {}})
    from sphere_jax.eval import repeatability
    with open(f"{after}/lrf_results.md", "w") as f:         # the title the adapting run writes
        f.write(f"# LRF repeatability (rotated){repeatability.ADAPTED} (50 steps, no ground "
                f"truth read)\n")
    text = publish.adaptation_section(before, after)
    assert "## Adaptation without labels, compass adapted: LRF repeatability (rotated) on " \
           "/data/bunny" in text
    assert "| method | repeatability: before | after | change | mean angle (degrees): " \
           "before | after |" in text
    assert "| compass | 0.200 | 0.300 | +50% | 90.0 | 70.5 |" in text
    assert "| flare | 0.400 | 0.400 | +0% | 60.0 | 60.0 |" in text
    assert "compass: 50 steps" in text and f"(`{adapted}`)" in text
    with pytest.raises(ValueError, match="two runs of one task"):
        publish.adaptation_section(before, _registration_run(tmp_path, "reg", {}, {}))


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
    rows = {t: (v, ok) for t, v, ok in standing.rows(*runs)}
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
    """A run's card entry is named by its title and data; rerun in the same workdir on data
    that moved, it replaces its old entry instead of standing beside it."""
    path = _compass_bundle(tmp_path / "bundle", 1)
    for root in ("/old/place", "runs/new_place"):
        model_card.add_evaluation(path, f"LRF repeatability on {root}", "| x |",
                                  f"python -m experiments.evaluate --config.data.root={root} "
                                  f"--workdir=runs/lrf")
    model_card.add_evaluation(path, "LRF repeatability on /elsewhere", "| y |",
                              "python -m experiments.evaluate --workdir=runs/other")
    model_card.add_evaluation(path, "LRF repeatability on /moved", "| z |",       # absl takes
                              "python -m experiments.evaluate --workdir runs/other")  # both forms
    card = (path / model_card.CARD).read_text()
    assert "on runs/new_place" in card and "/old/place" not in card and "/elsewhere" not in card
    assert "on /moved" in card


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
    readme = tmp_path / "README.md"
    readme.write_text("a\n<!-- classification-targets:begin -->\nold\n"
                      "<!-- classification-targets:end -->\nb\n")
    publish.publish([], results=str(tmp_path / "results.md"), readme=str(readme),
                    classification=str(run))
    text = readme.read_text()
    assert "| Compass + PointNet: AR accuracy ≥ 0.72 (the thesis's 72.2 %) | 0.700 | **no** |" \
        in text and "old" not in text and text.endswith("end -->\nb\n")
