"""Evaluation tasks as plug-ins: ``config.task`` names a module of this package whose
``TASK`` (a :class:`Task`) says how to run the whole evaluation and what to check before it.
``python -m experiments.evaluate`` is a thin main over :func:`run`.

A new task is a module with a ``TASK = tasks.Task(run=...)`` and one line in :data:`TASKS`.
"""
from __future__ import annotations

import dataclasses
import datetime
import importlib
import json
import os
import time
import warnings
from typing import Any, Callable, Iterable, Optional

from sphere_jax import checks, paths, workdirs
from sphere_jax.bundles import store
from sphere_jax.data.readers import io
from sphere_jax.eval import resume
from sphere_jax.features import methods, registry
from sphere_jax.models import shipped

TASKS = {
    "registration": "sphere_jax.eval.registration",      # seed 4.1-4.4: FMR, inlier ratio, RR
    "lrf": "sphere_jax.eval.repeatability",              # seed 3.2: LRF repeatability
    "classification": "sphere_jax.eval.classification",  # seed 3.3: NR / AR accuracy
    "recognition": "sphere_jax.eval.recognition",        # seed ch. 5: Saliency Boost
    "objects": "sphere_jax.eval.objects",                # seed ch. 6: colour + shape
    "pose": "sphere_jax.eval.pose",                      # seed ch. 7: pose pipeline
    "ablation": "sphere_jax.eval.ablation",              # seed Table 4.5: LEAD variants
}


@dataclasses.dataclass(frozen=True)
class Task:
    """What an evaluation task gives :func:`run`.

    Attributes:
      run: ``(config, workdir, progress) -> (rows, markdown)``: the whole evaluation; writes
        its tables (:mod:`report`: markdown + CSV) and plots in ``workdir`` and returns them.
      methods: ``() -> keys`` the task's ``config.methods`` may name; checked, with the
        bundles they need, before any work. None: the task reads no ``config.methods``.
      check_data: ``(config) -> None``: refuses a data root without scans before the workdir
        is claimed.
      kept: ``(workdir, config) -> int``: results an interrupted run kept (then the record's
        wall time is not this run's); None: :func:`sphere_jax.eval.resume.kept` over the
        config's bundles.
      bundles: ``(config) -> {name: path}`` of a task whose config has no ``bundles`` (the
        classification's classifiers and whole-shape Compass), for the run's record.
      summary: ``(folder) -> markdown``: the run's published tables (one per run, methods by
        metrics), read from the CSV and JSON files of its workdir or of its record
        (``experiments.publish`` keeps those in docs/records). None: not publishable.
    """
    run: Callable[[Any, str, bool], tuple]
    methods: Optional[Callable[[], Iterable[str]]] = None
    check_data: Optional[Callable[[Any], None]] = None
    kept: Optional[Callable[[str, Any], int]] = None
    bundles: Optional[Callable[[Any], dict]] = None
    summary: Optional[Callable[[str], str]] = None


def task(name) -> Task:
    """The :class:`Task` of ``config.task`` ``name`` (its module is imported on demand: each
    pulls in its own libraries)."""
    if name not in TASKS:
        raise checks.ConfigError("config.task", f"one of {', '.join(TASKS)}", name)
    return importlib.import_module(TASKS[name]).TASK


RUN_RECORD = "run.json"


def read_record(folder) -> dict:
    """The ``run.json`` of an evaluation workdir (or of its record in docs/records)."""
    path = os.path.join(str(folder), RUN_RECORD)
    if not os.path.isfile(path):
        raise checks.MissingError(f"{folder} has no {RUN_RECORD}: not an experiments.evaluate "
                                  f"workdir")
    with open(path) as f:
        return json.load(f)


def run(config, workdir, progress=True, command=None):
    """Run the evaluation ``config.task``; returns ``(rows, markdown)``. Config values are
    checked first (:func:`sphere_jax.checks.config_values`). ``workdir/run.json`` records
    what produced the tables: the command, the config, the bundles (folder and steps done),
    the date and the wall time (``experiments.publish`` stamps the docs' tables with it)."""
    spec = task(config.task)
    checks.config_values(config)
    chosen = bundle_paths(config) if "bundles" in config else {}
    if spec.methods is not None:                  # names and bundles, before any work
        check_bundles(config, method_names(config, tuple(spec.methods())), chosen)
    if spec.check_data is not None:               # and a data root without scans
        spec.check_data(config)
    start = time.perf_counter()
    # Results kept by an interrupted run (eval/resume.py): its wall time is not this run's.
    resumed = (spec.kept(workdir, config) if spec.kept is not None
               else resume.kept(workdir, config, chosen)) > 0
    import jax
    with workdirs.claimed(workdir, command, primary=jax.process_index() == 0):
        rows, md = spec.run(config, workdir, progress)
    if md:                                        # in a multi-process run: process 0 only
        record = {"command": command, "task": config.task, "config": config.to_dict(),
                  "bundles": bundles_used(config, chosen),
                  "date": datetime.date.today().isoformat(),
                  "wall_s": round(time.perf_counter() - start, 1), "resumed": resumed}
        io.atomic_write(os.path.join(workdir, RUN_RECORD),
                        json.dumps(record, indent=1, default=str).encode())
    return rows, md


def bundles_used(config, chosen=None):
    """Kind -> ``{'path', 'steps_done', 'fingerprint'}`` of the bundles an evaluation config
    names (the classification's whole-shape Compass as ``compass_shapes``); ``chosen`` is
    :func:`bundle_paths` where the caller has it."""
    from sphere_jax.bundles import inference
    out = {}
    if "bundles" in config:
        chosen = bundle_paths(config) if chosen is None else chosen
        names = [_key(m) for m in str(config.get("methods", "")).split(",") if m.strip()]
        if names:                                     # only the kinds the methods use
            chosen = {k: v for k, v in chosen.items() if k in _kinds(names)}
    else:                                             # a task that names its own bundles
        spec = task(config.task)
        chosen = spec.bundles(config) if spec.bundles is not None else {}
    for kind, path in sorted(chosen.items()):
        path = inference.bundle_path(path) if path else path
        if path and store.is_bundle(path):
            inside = not paths.relative(path).startswith("..")
            out[kind] = {"path": paths.relative(path) if inside else paths.portable(path),
                         "steps_done": store.steps_done(store.read_config(path)),
                         "fingerprint": store.fingerprint(path)}
    return out


def bundle_paths(config):
    """Kind -> bundle path: the config's defaults, ``config.bundle`` replacing its kind's."""
    paths = dict(config.bundles.to_dict())
    if config.bundle:
        if not store.is_bundle(config.bundle):
            raise checks.ConfigError("config.bundle", "a bundle folder (with config.json)",
                                     config.bundle)
        paths[store.read_config(config.bundle).model] = config.bundle
    return paths


def check_bundles(config, names, chosen=None):
    """:class:`~sphere_jax.checks.ConfigError` naming a bundle field of ``config`` that the
    methods ``names`` need and that is not a bundle folder (``chosen``:
    :func:`bundle_paths`, where the caller has it)."""
    if "bundles" not in config:
        return
    from sphere_jax.bundles import inference
    chosen = bundle_paths(config) if chosen is None else chosen
    needed = _kinds(names)
    for kind, path in sorted(chosen.items()):
        # A bundle set away from the shipped one for a kind no chosen method uses is a
        # mistake worth a line (e.g. --config.bundles.lead=... with methods=shot,usc).
        if path and kind not in needed and shipped.bundle_path(kind) != path:
            warnings.warn(f"config.bundles.{kind}={path!r} is not used: none of the methods "
                          f"{', '.join(names)} needs a {kind} bundle", stacklevel=2)
    for kind in sorted(needed):
        path = chosen.get(kind)
        if not path:
            continue
        if not store.is_bundle(inference.bundle_path(path)):
            raise checks.ConfigError(f"config.bundles.{kind}",
                                     "a bundle folder (with config.json)", path)
        model = store.read_config(inference.bundle_path(path)).model
        if model != kind:
            raise checks.ConfigError(f"config.bundles.{kind} must be a {kind} bundle; got "
                                     f"{path!r}, a {model} bundle")


def _kinds(names) -> set:
    """The bundle kinds the methods ``names`` (keys) need."""
    out = set()
    for m in names:
        try:
            out.update(registry.needs(m))
        except checks.InputError:               # a task's own method (ransac): no bundle
            pass
    return out


def _key(name):
    """A method's key (:mod:`~sphere_jax.features.registry`), or ``name`` itself (an LRF, or
    unknown: the caller says so)."""
    name = name.strip()
    try:
        return registry.resolve(name).key
    except ValueError:
        return name


def method_names(config, known):
    """The keys of the methods ``config.methods`` names (grammar names or keys);
    :class:`~sphere_jax.checks.ConfigError` unless each is one of ``known``."""
    names = [_key(m) for m in config.methods.split(",") if m.strip()]
    bad = [m for m in names if m not in known]
    twice = sorted({m for m in names if names.count(m) > 1})
    if twice and not bad:
        raise checks.ConfigError(f"config.methods must name each method once; got "
                                 f"{config.methods!r} ({', '.join(twice)} more than once)")
    if bad or not names:
        raise checks.ConfigError(
            "config.methods", f"a comma-separated list of {', '.join(known)}"
            + (f" ({', '.join(bad)} unknown)" if bad else ""), config.methods)
    return names


def chosen_methods(config, known, bundles):
    """:func:`method_names`, less those whose bundle is missing from ``bundles`` (skipped with
    a warning)."""
    names = method_names(config, known)
    missing = methods.bundles_needed(names, bundles)
    for m in missing:
        warnings.warn(f"method {m!r} skipped: no bundle for {registry.needs(m)} "
                      f"(set --config.bundle or --config.bundles.<kind>)", stacklevel=2)
    names = [m for m in names if m not in missing]
    if not names:
        raise checks.ConfigError("config.methods", "methods whose bundles are set", config.methods)
    return names
