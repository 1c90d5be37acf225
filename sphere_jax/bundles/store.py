"""Inference bundles on disk: what training writes and the API loads.

A bundle is a folder::

    bundle/config.json          the training config (ml_collections JSON)
    bundle/variables/           params + batch_stats (an orbax StandardCheckpoint)
    bundle/training_data.json   what the bundle was trained on: folders, scans, patches

A bundle is written whole into a temporary folder beside it and swapped in
(:func:`sphere_jax.files.swap_folders`): a full disk or a kill mid-write leaves the previous
bundle as it was. A folder whose ``config.json`` is missing is not a bundle.
:func:`sphere_jax.bundles.inference.load_bundle` turns a folder into a model; this module only
reads and writes the files.
"""
from __future__ import annotations

import gc
import hashlib
import inspect
import json
import logging
import os
import shutil
import sys
import time

import jax
import ml_collections
import numpy as np
import orbax.checkpoint as ocp

from sphere_jax import files
from sphere_jax.checks import BundleError

CONFIG = "config.json"
VARIABLES = "variables"
TRAINING_DATA = "training_data.json"
WHITENING = "whitening.npz"        # descriptor whitening (sphere_jax.bundles.whitening)


def write_json(path, text):
    """Write ``text`` to ``path`` atomically (:func:`sphere_jax.files.atomic_write`)."""
    files.atomic_write(path, text)


def read_json(bundle_dir, name) -> dict:
    """The bundle's JSON file ``name`` (``evaluations.json``, ``whitening.json``); ``{}`` when
    the bundle has none."""
    path = os.path.join(str(bundle_dir), name)
    if not os.path.isfile(path):
        return {}
    with open(path) as f:
        return json.load(f)


def save(path, config, variables, training_data=None):
    """Write a bundle folder ``path`` (created if missing); returns its absolute path.
    ``variables``: ``{'params', 'batch_stats'}``; ``training_data``: a JSON-able statement of
    the training data (see :meth:`sphere_jax.data.patch_source.PatchSource.statement`)."""
    path = os.path.abspath(str(path))
    # In a multi-host run every process calls this (orbax's save is collective) with the same
    # folder; the files themselves are written by process 0.
    primary = jax.process_index() == 0
    tmp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.writing")
    if primary:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)           # a run killed mid-write
        os.makedirs(tmp)
    try:
        with ocp.StandardCheckpointer() as ckpt:
            # Host copies: a bundle does not depend on the devices it was trained on.
            ckpt.save(os.path.join(tmp, VARIABLES),
                      jax.tree_util.tree_map(np.asarray, variables))
        if primary:
            write_json(os.path.join(tmp, CONFIG), config.to_json(indent=1))
            if training_data is not None:
                write_json(os.path.join(tmp, TRAINING_DATA),
                           json.dumps(training_data, indent=1))
            if os.path.isdir(path):     # its card's evaluations were of the old weights
                files.swap_folders(tmp, path)
            else:
                os.replace(tmp, path)
    except BaseException:
        if primary:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    return path



def steps_done(config) -> int:
    """The training steps a bundle's ``config`` has done (``train.steps`` for bundles that
    ran their plan before ``steps_done`` was recorded)."""
    return int(config.train.get("steps_done", config.train.steps))


def is_bundle(path) -> bool:
    return os.path.isfile(os.path.join(str(path), CONFIG))


def read_config(path) -> ml_collections.ConfigDict:
    """The config a bundle was trained with."""
    path = os.path.abspath(str(path))
    if not is_bundle(path):
        raise BundleError(path, f"not a bundle (no {CONFIG}: a bundle is the 'bundle' folder "
                                "a training run writes)")
    try:
        with open(os.path.join(path, CONFIG)) as f:
            config = ml_collections.ConfigDict(json.load(f))
    except (OSError, ValueError) as e:
        raise BundleError(path, f"{CONFIG} is unreadable ({type(e).__name__}: {e})") from None
    if not isinstance(config.get("model"), str) or "data" not in config:
        raise BundleError(path, f"{CONFIG} is not a training config (no 'model' or 'data')")
    return config


def read_variables(path) -> dict:
    """The bundle's ``{'params', 'batch_stats'}`` on this process's default device, whatever
    devices they were saved from."""
    target = os.path.join(os.path.abspath(str(path)), VARIABLES)
    if not os.path.isdir(target):
        inner = os.path.join(str(path), "bundle")
        hint = f"; a training or adaptation workdir? its bundle is {inner}" \
            if os.path.isdir(os.path.join(inner, VARIABLES)) else ""
        raise BundleError(path, f"no {VARIABLES}/ folder (the weights){hint}")

    def restore():
        with ocp.StandardCheckpointer() as ckpt:
            meta = ckpt.metadata(target)
            tree = getattr(meta, "item_metadata", meta)
            device = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
            abstract = jax.tree_util.tree_map(
                lambda m: jax.ShapeDtypeStruct(m.shape, m.dtype, sharding=device), tree)
            return ckpt.restore(target, abstract)

    variables, reason = restore_quietly(restore)
    if reason is None:
        return variables
    raise BundleError(path, f"the weights in {VARIABLES}/ cannot be restored (corrupt or "
                            f"incomplete): {reason}")


def restore_quietly(restore):
    """``(restore(), None)``, or ``(None, reason)`` when the orbax restore fails (orbax and
    TensorStore report corruption in many exception types; ``reason`` is the first line).

    When one shard's read fails, orbax's event loop closes while TensorStore's threads still
    finish the others (each then reports "Event loop is closed"), and the pending coroutines
    and tasks report their exceptions when the garbage collector finds them, whenever that is.
    On CPython 3.11 a report printed while the interpreter builds an AST (an import, a
    traceback) corrupts the ast module's shared recursion counter (CPython gh-106905): a test
    run died of it at its very end. The caller reports the failure itself, so these reports
    are dropped (asyncio's log is muted meanwhile) and the abandoned coroutines are collected
    at once, outside the ``except`` whose traceback keeps them alive; anything else
    unraisable still reaches the hook.
    """
    hook = sys.unraisablehook

    def drop_abandoned(unraisable):
        closed_loop = (isinstance(unraisable.exc_value, RuntimeError)
                       and str(unraisable.exc_value) == "Event loop is closed")
        if not (closed_loop or inspect.iscoroutine(unraisable.object)):
            hook(unraisable)

    asyncio_log = logging.getLogger("asyncio")     # "Task exception was never retrieved"
    level = asyncio_log.level
    sys.unraisablehook = drop_abandoned
    asyncio_log.setLevel(logging.CRITICAL + 1)
    try:
        try:
            return restore(), None
        except Exception as e:
            reason = first_line(e)
        time.sleep(0.05)          # TensorStore's threads report within milliseconds
        gc.collect()
        return None, reason
    finally:
        sys.unraisablehook = hook
        asyncio_log.setLevel(level)


def first_line(error) -> str:
    """The first line of a third-party error (TensorStore's run to a hundred)."""
    text = str(error).strip().splitlines()
    text = text[0].split(". See full")[0][:200] if text else ""
    return f"{type(error).__name__}: {text}"


def check_fits(path, variables, expected):
    """Raise :class:`BundleError` naming the first parameter of ``variables`` whose path or
    shape differs from ``expected`` (the abstract variables of the bundle's config's model)."""
    have, want = tree_shapes(variables), tree_shapes(expected)
    for key in sorted(set(have) | set(want)):
        if key not in have:
            raise BundleError(path, f"its config's model needs parameter {key} "
                                    f"{want[key]}, which the weights lack")
        if key not in want:
            raise BundleError(path, f"the weights hold parameter {key}, which its config's "
                                    f"model does not have (config and weights do not match)")
        if have[key] != want[key]:
            raise BundleError(path, f"parameter {key} has shape {have[key]} in the weights, "
                                    f"{want[key]} in its config's model (config and weights "
                                    f"do not match)")


def tree_shapes(tree) -> dict:
    """Parameter path (``['params']['Dense_0']['kernel']``) -> shape, of arrays, abstract
    arrays or orbax metadata alike."""
    return {jax.tree_util.keystr(k): tuple(v.shape)
            for k, v in jax.tree_util.tree_flatten_with_path(tree)[0]}


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
    """Changes when the bundle is rewritten or its whitening refitted (for caches keyed on the
    folder)."""
    files = [os.path.join(os.path.abspath(str(path)), n) for n in (CONFIG, WHITENING)]
    times = tuple(os.stat(f).st_mtime_ns if os.path.isfile(f) else None for f in files)
    return None if times[0] is None else times


def variables_digest(variables) -> str:
    """A hash of a variable tree's names, shapes, dtypes and values: which weights a fine-tune
    or an adaptation started from, wherever they were loaded from."""
    digest = hashlib.sha256()
    for key, leaf in jax.tree_util.tree_flatten_with_path(variables)[0]:
        leaf = np.asarray(leaf)
        digest.update(f"{jax.tree_util.keystr(key)}|{leaf.shape}|{leaf.dtype}".encode() + b"\0")
        digest.update(np.ascontiguousarray(leaf).tobytes())
    return digest.hexdigest()[:16]


def fingerprint(path) -> str | None:
    """A hash of what decides the bundle's outputs — its config, variables and descriptor
    whitening, not the model card that evaluations complete — the same in any checkout
    (None: not a bundle)."""
    path = os.path.abspath(str(path))
    if not is_bundle(path):
        return None
    digest = hashlib.sha256()
    files = [CONFIG] + ([WHITENING] if os.path.isfile(os.path.join(path, WHITENING))
                        else []) + sorted(
        os.path.relpath(os.path.join(root, name), path)
        for root, _, names in os.walk(os.path.join(path, VARIABLES)) for name in names)
    for rel in files:
        digest.update(rel.replace(os.sep, "/").encode() + b"\0")
        with open(os.path.join(path, rel), "rb") as f:
            digest.update(hashlib.sha256(f.read()).digest())
    return digest.hexdigest()[:16]
