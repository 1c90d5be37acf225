"""Inference bundles on disk: what training writes and the API loads.

A bundle is a folder::

    bundle/config.json          the training config (ml_collections JSON)
    bundle/variables/           params + batch_stats (an orbax StandardCheckpoint)
    bundle/training_data.json   what the bundle was trained on: folders, scans, patches

The JSON files are written under a temporary name and renamed into place, the variables
first: a folder whose ``config.json`` is missing is not a bundle. :func:`sphere_jax.api.load_bundle`
turns a folder into a model; this module only reads and writes the files.
"""
from __future__ import annotations

import json
import os
import shutil

import jax
import ml_collections
import numpy as np
import orbax.checkpoint as ocp

CONFIG = "config.json"
VARIABLES = "variables"
TRAINING_DATA = "training_data.json"


def _write_json(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def save(path, config, variables, training_data=None):
    """Write a bundle folder ``path`` (created if missing); returns its absolute path.
    ``variables``: ``{'params', 'batch_stats'}``; ``training_data``: a JSON-able statement of
    the training data (see :meth:`sphere_jax.data.pipeline.PatchSource.statement`)."""
    path = os.path.abspath(str(path))
    # In a multi-host run every process calls this (orbax's save is collective); the files
    # themselves are written by process 0.
    primary = jax.process_index() == 0
    target = os.path.join(path, VARIABLES)
    if primary:
        os.makedirs(path, exist_ok=True)
        if os.path.exists(target):
            shutil.rmtree(target)
    with ocp.StandardCheckpointer() as ckpt:
        # Host copies: a bundle does not depend on the devices it was trained on.
        ckpt.save(target, jax.tree_util.tree_map(np.asarray, variables))
    if primary:
        _write_json(os.path.join(path, CONFIG), config.to_json(indent=1))
        if training_data is not None:
            _write_json(os.path.join(path, TRAINING_DATA), json.dumps(training_data, indent=1))
    return path


def is_bundle(path) -> bool:
    return os.path.isfile(os.path.join(str(path), CONFIG))


def read_config(path) -> ml_collections.ConfigDict:
    """The config a bundle was trained with."""
    path = os.path.abspath(str(path))
    if not is_bundle(path):
        raise FileNotFoundError(f"{path} is not a bundle (no {CONFIG})")
    with open(os.path.join(path, CONFIG)) as f:
        return ml_collections.ConfigDict(json.load(f))


def read_variables(path) -> dict:
    """The bundle's ``{'params', 'batch_stats'}`` on this process's default device, whatever
    devices they were saved from."""
    target = os.path.join(os.path.abspath(str(path)), VARIABLES)
    with ocp.StandardCheckpointer() as ckpt:
        meta = ckpt.metadata(target)
        tree = getattr(meta, "item_metadata", meta)
        device = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
        abstract = jax.tree_util.tree_map(
            lambda m: jax.ShapeDtypeStruct(m.shape, m.dtype, sharding=device), tree)
        return ckpt.restore(target, abstract)


def read_training_data(path) -> dict:
    """The bundle's training-data statement; bundles written before it existed get the
    folders of their config and no counts."""
    file = os.path.join(str(path), TRAINING_DATA)
    if os.path.isfile(file):
        with open(file) as f:
            return json.load(f)
    roots = [r.strip() for r in str(read_config(path).data.get("root", "")).split(",")
             if r.strip()]
    return {"folders": {r: None for r in (roots or ["embedded"])}, "counts": "not recorded"}


def stamp(path):
    """Changes when the bundle is rewritten (for caches keyed on the folder)."""
    cfg = os.path.join(os.path.abspath(str(path)), CONFIG)
    return os.stat(cfg).st_mtime_ns if os.path.isfile(cfg) else None
