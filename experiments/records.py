"""The records of published runs: what every published figure is regenerated from.

``docs/records/<name>/`` keeps the small files of one evaluation workdir — its ``run.json``
(command, config, bundles, date) and its CSV and JSON tables, never checkpoints or plots — and
``docs/records/<ADAPTATION><name>/adaptation.json`` one before/after comparison. The workdirs
themselves (``runs/``) stay out of the repository. ``docs/records/published.json`` says what
is published where::

    {"sections": [name, ...],       # docs/results.md, in this order
     "headline": name,              # the README's main-job table
     "targets": [name, ...],        # the README's targets table (experiments/standing.py)
     "classification": name,        # the README's classification targets
     "registered": [name, ...],     # docs/registered.md (experiments.registered runs)
     "bench": [name, ...]}          # docs/performance.md's blocks (experiments.bench --record)

``experiments.publish`` writes records and renders every generated document from them;
``publish --check`` renders again and compares.
"""
from __future__ import annotations

import importlib
import json
import os
import shutil

from sphere_jax import checks, files
from sphere_jax.eval import tasks

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROOT = os.path.join(REPO, "docs", "records")
INDEX = "published.json"
ADAPTATION = "adaptation-"              # the name prefix of a before/after comparison
COMPARISON = "adaptation.json"
KEPT = (".csv", ".json")                # the top-level files of a workdir a record keeps
EMPTY = {"sections": [], "headline": None, "targets": [], "classification": None,
         "registered": [], "bench": []}
BENCH = "bench.json"                    # a benchmark's record: experiments.bench --record
# Records of runs that are not ``experiments.evaluate`` tasks: the module whose
# ``summary(folder)`` renders them.
SUMMARIES = {"registered": "sphere_jax.eval.registered"}


def summary(folder) -> str:
    """A record's (or a workdir's) published markdown: its task's ``summary``."""
    task = tasks.read_record(folder)["task"]
    if task in SUMMARIES:
        return importlib.import_module(SUMMARIES[task]).summary(folder)
    render = tasks.task(task).summary
    if render is None:
        raise checks.InputError("folder", "a run of a task with a published summary "
                                "(registration, lrf, classification, registered)",
                                f"a {task} run ({folder})")
    return render(folder)


def folder(name, root=ROOT) -> str:
    path = os.path.join(root, name)
    if not os.path.isdir(path):
        raise checks.MissingError(f"no record {name!r} in {root} (python -m "
                                  f"experiments.publish RUN_DIR makes one)")
    return path


def name_of(run_dir) -> str:
    """A workdir's record name: its folder's name."""
    return os.path.basename(os.path.normpath(os.path.abspath(str(run_dir))))


def save(run_dir, root=ROOT) -> str:
    """Copy the workdir's ``run.json`` and top-level CSV and JSON files into its record,
    replacing an older record of the same name; returns the name. Refused for a folder that
    is not an evaluation workdir or whose task has no published summary."""
    summary(run_dir)                                  # refused before anything is copied
    name = name_of(run_dir)
    if name.startswith(ADAPTATION):
        raise checks.InputError("run_dir", f"a folder whose name does not start with "
                                f"{ADAPTATION!r} (the comparisons' records)", name)
    kept = sorted(f for f in os.listdir(run_dir) if f.endswith(KEPT)
                  and os.path.isfile(os.path.join(run_dir, f)))
    target = os.path.join(root, name)
    shutil.rmtree(target, ignore_errors=True)
    os.makedirs(target)
    for f in kept:
        shutil.copyfile(os.path.join(run_dir, f), os.path.join(target, f))
    return name


def save_bench(run_dir, root=ROOT) -> str:
    """Copy ``run_dir/bench.json`` (``experiments.bench --record=DIR``) to the record
    ``bench-<suite>``, replacing the suite's older one; returns its name."""
    path = os.path.join(str(run_dir), BENCH)
    if not os.path.isfile(path):
        raise checks.MissingError(f"{run_dir} has no {BENCH}: run python -m experiments.bench "
                                  f"--suite=NAME --record={run_dir}")
    with open(path) as f:
        name = f"bench-{json.load(f)['suite']}"
    os.makedirs(os.path.join(root, name), exist_ok=True)
    shutil.copyfile(path, os.path.join(root, name, BENCH))
    return name


def read_bench(name, root=ROOT) -> dict:
    with open(os.path.join(folder(name, root), BENCH)) as f:
        return json.load(f)


def save_comparison(name, comparison: dict, root=ROOT) -> str:
    """Write a before/after comparison's record ``<ADAPTATION><name>``; returns its name."""
    key = f"{ADAPTATION}{name}"
    os.makedirs(os.path.join(root, key), exist_ok=True)
    files.atomic_write(os.path.join(root, key, COMPARISON),
                       json.dumps(comparison, indent=1, sort_keys=True) + "\n")
    return key


def read_comparison(name, root=ROOT) -> dict:
    with open(os.path.join(folder(name, root), COMPARISON)) as f:
        return json.load(f)


def read_index(root=ROOT) -> dict:
    path = os.path.join(root, INDEX)
    if not os.path.isfile(path):
        return dict(EMPTY)
    with open(path) as f:
        return {**EMPTY, **json.load(f)}


def write_index(index: dict, root=ROOT):
    """Write the index and remove the records it no longer names."""
    os.makedirs(root, exist_ok=True)
    named = (set(index["sections"]) | set(index["targets"]) | set(index["registered"])
             | set(index["bench"]) | {index["headline"], index["classification"]})
    for name in os.listdir(root):
        if os.path.isdir(os.path.join(root, name)) and name not in named:
            shutil.rmtree(os.path.join(root, name))
    files.atomic_write(os.path.join(root, INDEX), json.dumps(index, indent=1) + "\n")
