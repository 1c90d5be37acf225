"""The command lines: a bad flag, config, field or value is one line on stderr, exit status 2,
before any work (no traceback, no workdir written)."""
import json
import os
import subprocess
import sys

import pytest

from experiments import cli

# Every case starts a fresh interpreter (JAX, flax, open3d): ~5 s each.
pytestmark = pytest.mark.slow

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


@pytest.mark.parametrize("args, message", [
    (["experiments.train", "--config=lead:tiny", "--config.train.stepz=5"],
     "train: error: unknown field config.train.stepz in --config.train.stepz; the fields of "
     "config.train are: batch_size, checkpoint_every"),
    (["experiments.train", "--config=leed"], "train: error: --config must be one of ablation, "),
    (["experiments.train", "--config=lead:huge"],
     "must be one of ('paper', 'mid', 'small', 'tiny'); got 'huge'"),
    (["experiments.train", "--config", "lead:huge"],              # a space, not '='
     "must be one of ('paper', 'mid', 'small', 'tiny'); got 'huge'"),
    (["experiments.train", "--config=lead:tiny", "--config.train.steps=-5"],
     "train: error: config.train.steps must be an integer >= 1; got -5"),
    (["experiments.train", "--config=lead:tiny", "--config.train.learning_rate=nan"],
     "config.train.learning_rate must be a finite number > 0; got nan"),
    (["experiments.evaluate", "--config=eval_registration", "--config.data.max_pairs=-1"],
     "evaluate: error: config.data.max_pairs must be an integer >= 0 (0: every pair); got -1"),
    (["experiments.train", "--config=lead:tiny", "--config.data.root=embedded:1,/nonexistent"],
     "train: error: config.data.root must be comma-separated scan files or folders"),
    (["experiments.train", "--config=lead:tiny", "--config.train.pack=/nonexistent"],
     "train: error: config.train.pack must be a folder made by python -m "
     "experiments.make_data --pack=ROOTS --out=DIR; got '/nonexistent'"),
    (["experiments.evaluate", "--config=eval_registration", "--config.methods=lead,foo"],
     "evaluate: error: config.methods must be a comma-separated list of fpfh, "),
    (["experiments.evaluate", "--config=eval_registration", "--config.methods=lead",
      "--config.bundles.lead=/tmp"],
     "evaluate: error: config.bundles.lead must be a bundle folder (with config.json)"),
    (["experiments.evaluate", "--config=eval_lrf", "--config.methods=compass",
      "--config.bundles.compass=sphere_jax/weights/lead_mid/bundle"],
     "evaluate: error: config.bundles.compass must be a compass bundle; got "),
    (["experiments.evaluate", "--config=eval_registration", "--config.methods=lead,shot,lead"],
     "evaluate: error: config.methods must name each method once; got 'lead,shot,lead' (lead "),
    (["experiments.evaluate", "--config=eval_registration", "--config.data.root=docs"],
     "evaluate: error: config.data.root: docs: no Stanford .conf, no cloud_bin_K.ply"),
    (["experiments.evaluate", "--config=eval_registration", "--config.seed=-1"],
     "evaluate: error: config.seed must be an integer >= 0; got -1"),
    (["experiments.train", "--config=lead:tiny", "--config.model=pointnet2"],
     "train: error: config.model must be one of compass, lead"),
    (["experiments.train", "--config=lead:tiny", "--config.train.final_lr_fraction=2"],
     "train: error: config.train.final_lr_fraction must be a finite number >= 0 and at most 1"),
    (["experiments.train", "--config=lead:tiny", "--config.train.schedule=warmup_cosine",
      "--config.train.warmup_steps=100000"],
     "train: error: config.train.warmup_steps must be below config.train.steps"),
    (["experiments.bench", "--suite=nope"], "bench: error: flag --suite=nope: value should be"),
])
def test_bad_command_lines_are_one_line_and_status_2(args, message, tmp_path):
    out = run(*args, f"--workdir={tmp_path / 'w'}" if "bench" not in args[0] else "--json")
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], out.stderr
    assert not (tmp_path / "w").exists()


def test_an_unknown_scene_is_one_line_naming_the_scenes(tmp_path):
    out = run("experiments.evaluate", "--config=eval_registration:quick",
              "--config.data.scenes=nosuch", f"--workdir={tmp_path / 'w'}")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "config.data.scenes must be comma-separated scene names among" in out.stderr


@pytest.mark.parametrize("args, message", [
    (["experiments.adapt", "--bundle=nope", "--data=x"], "adapt: error: bundle "),
    (["experiments.adapt", "--bundle=lead", "--data=/nonexistent"],
     "adapt: error: data root '/nonexistent' is neither a scan file nor a folder"),
    (["experiments.adapt", "--bundle=lead", "--data=.", "--minutes=0"],
     "adapt: error: argument --minutes: expected a positive number, got '0'"),
    (["experiments.adapt", "--bundle=lead"], "adapt: error: the following arguments are "
                                             "required: --data"),
    (["experiments.adapt", "--bundle=lead", "--data=.", "--patience=-1"],
     "adapt: error: argument --patience: expected a non-negative integer, got '-1'"),
    (["experiments.adapt", "--bundle=lead", "--data=.", "--learning_rate=0"],
     "adapt: error: argument --learning_rate: expected a positive number, got '0'"),
    (["experiments.adapt", "--bundle=lead", "--data=.", "--voxel=abc"],
     "adapt: error: argument --voxel: expected 'auto' or a positive number, got 'abc'"),
    (["experiments.register", "a.ply", "b.ply", "--radius=-1"],
     "register: error: argument --radius: expected 'auto' or a positive number, got '-1'"),
    (["experiments.register", "/nonexistent.ply", "b.ply"], "register: error: "
                                                            "/nonexistent.ply: no such file"),
    (["experiments.register", "a.ply", "b.ply", "--method=nope"],
     "register: error: argument --method: invalid choice: 'nope'"),
    (["experiments.register", "a.ply", "b.ply", "--keypoints=-3"],
     "register: error: argument --keypoints: expected a positive integer, got '-3'"),
    (["experiments.register", "a.ply", "b.ply", "--min-fitness=2"],
     "register: error: argument --min-fitness: expected a number in [0, 1], got '2'"),
    (["experiments.register", "a.ply", "b.ply", "--adapt=nan"],
     "register: error: argument --adapt: expected a positive number, got 'nan'"),
    (["experiments.make_data", "--voxel=-1", "--pack=embedded:0"],
     "make_data: error: argument --voxel: expected a positive number, got '-1'"),
    (["experiments.make_data", "--voxel=0.05"],
     "make_data: error: --voxel is the pack's voxel: give it with --pack"),
    (["experiments.make_data", "--scenes=0"],
     "make_data: error: argument --scenes: expected a positive integer, got '0'"),
    (["experiments.make_data", "--scenes=3", "--lidar=x"],
     "make_data: error: --scenes is for the default data, not --pack, --lidar or "
     "--validation"),
    (["experiments.make_data", "--pack=/nonexistent"],
     "make_data: error: data root '/nonexistent' is neither"),
    (["experiments.model_card", "/nonexistent"], "model_card: error: bundle /nonexistent: "
                                                 "not a bundle"),
    (["experiments.publish", "/nonexistent"], "publish: error: /nonexistent has no run.json"),
    (["experiments.publish", "/nonexistent", "--adaptation=a"],
     "publish: error: --adaptation takes BEFORE_RUN:AFTER_RUN"),
    (["experiments.publish", "--targets=a,b,c"], "publish: error: --targets takes five runs"),
    (["experiments.publish"], "publish: error: nothing to publish"),
    (["experiments.make_data", "--lidar=/nonexistent"],
     "make_data: error: /nonexistent: no cloud_bin_K.ply fragments to scan"),
    (["experiments.make_data", "--pack=embedded:0", "--out=README.md"],
     "make_data: error: out_dir README.md/0-embedded_0 cannot be created: Not a directory"),
    (["experiments.bench", "--suite=describe", "--keypoints=0"],
     "bench: error: --keypoints must be a positive integer; got 0"),
    (["experiments.adapt", "--bundle=fpfh", "--data=x", "--workdir=w"],
     "adapt: error: bundle must be a bundle folder or one of compass, lead"),
    (["experiments.whiten", "--bundle=compass"],
     "whiten: error: bundle must be a descriptor bundle (lead, lead_pn, sound)"),
    (["experiments.whiten", "--bundle=lead", "--keypoints=0"],
     "whiten: error: argument --keypoints: expected a positive integer, got '0'"),
    (["experiments.whiten", "--bundle=/nonexistent"], "whiten: error: bundle /nonexistent"),
    (["experiments.whiten", "--bundle=lead", "--compass=lead_pn"],
     "whiten: error: compass must be a bundle that orients (compass)"),
    (["experiments.adapt", "--bundle=lead", "--data=embedded:1", "--compass=lead_pn"],
     "adapt: error: compass must be a bundle that orients (compass)"),
    (["experiments.adapt", "--bundle=,", "--data=x"],
     "adapt: error: bundle must be a bundle folder or kind, or several comma-separated; "
     "got ','"),
    (["experiments.adapt", "--bundle=lead,compass,lead", "--data=x"],
     "adapt: error: bundle must be one bundle per kind; got 2 lead bundles"),
])
def test_the_argparse_mains_refuse_in_one_line_with_status_2(args, message, tmp_path):
    """Each main's arguments (bundles, scans, files) are read before any work; a bad one is
    one line, exit status 2, and no output folder."""
    extra = {"experiments.adapt": [f"--workdir={tmp_path / 'w'}"],
             "experiments.make_data": [f"--out={tmp_path / 'w'}"],
             "experiments.register": [f"--out={tmp_path / 'w'}"]}.get(args[0], [])
    if args[-1] == "--bundle=lead" or any(a.startswith("--out=") for a in args):
        extra = []
    out = run(*args, *extra)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], out.stderr
    assert not (tmp_path / "w").exists()


def test_help_names_the_command_and_says_what_it_does_in_full():
    """``--help`` of an argparse main: the usage names the command as typed and the
    description is the docstring's whole first paragraph, not its first line cut short."""
    out = run("experiments.adapt", "--help")
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("usage: python -m experiments.adapt [-h] --bundle BUNDLE")
    text = " ".join(out.stdout.split())
    assert ("frame consistency) on your scans, for a number of minutes or steps, stopping "
            "early when the loss on held-back keypoints stops improving.") in text


@pytest.mark.parametrize("main", ["experiments.train", "experiments.evaluate"])
def test_unusable_or_busy_workdirs_are_one_line_and_status_2(main, tmp_path):
    from tests.test_workdirs import HOLD
    config = "--config=lead:tiny" if main.endswith("train") else "--config=eval_registration:tiny"
    (tmp_path / "file").write_text("x")
    out = run(main, config, f"--workdir={tmp_path / 'file' / 'w'}")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "cannot be created: Not a directory" in out.stderr
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path / "busy")], cwd=ROOT,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        out = run(main, config, f"--workdir={tmp_path / 'busy'}")
    finally:
        holder.kill()
        holder.wait()
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert f"is in use by process {holder.pid}" in out.stderr


def test_train_writes_a_whitened_bundle_with_its_card(tmp_path):
    """One command makes the whole descriptor bundle: the whitening is fitted on the training
    scans when the run finishes, and the card says so."""
    out = run("experiments.train", "--config=sound:tiny", "--config.train.steps=2",
              f"--workdir={tmp_path / 'w'}")
    assert out.returncode == 0, out.stderr[-2000:]
    statement = json.loads((tmp_path / "w" / "bundle" / "whitening.json").read_text())
    assert statement["default"]["keypoints"] > 10_000
    assert statement["default"]["command"].startswith("python -m experiments.train ")
    assert "descriptor whitening `default`" in (tmp_path / "w" / "bundle" /
                                                "MODEL_CARD.md").read_text()


def test_ctrl_c_is_one_line_and_status_130(capsys):
    """An interrupted main says so in one line (no traceback) and exits 130, as the shell
    reports SIGINT."""
    with pytest.raises(SystemExit) as stopped:
        with cli.refusals():
            raise KeyboardInterrupt
    assert stopped.value.code == 130
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "interrupted" in lines[0] and "same command" in lines[0]
