"""Evaluations that resume: each finished (method, scene) result is kept in the workdir as it
ends, and the same command after a kill redoes only what was not finished.

The results are keyed by everything that decides them — the evaluation config (without its
method list: each method's result stands alone) and the files of the bundles each method uses
— so a changed config starts afresh, and a retrained bundle redoes the methods that use it and
keeps the others, instead of mixing old and new results.
"""
from __future__ import annotations

import hashlib
import json
import os
import pickle
import re
import shutil

from sphere_jax.bundles import store
from sphere_jax import files
from sphere_jax.data import supports
from sphere_jax.features import registry

FOLDER = "finished"


class _Keys:
    """What a result is kept under: the folder ``key`` of the config (bundle paths aside: they
    differ between checkouts) and, per method, the ``tag`` of the bundles it uses."""

    def __init__(self, config, bundles: dict):
        settings = {k: v for k, v in config.to_dict().items()
                    if k not in ("methods", "bundles", "bundle")}
        text = json.dumps(settings, sort_keys=True, default=str)
        self.key = hashlib.sha256(text.encode()).hexdigest()[:16]
        self.prints = {k: store.fingerprint(p) for k, p in sorted(bundles.items()) if p}

    def tag(self, method):
        """Short hash of the fingerprints of the bundles ``method`` uses and of how its
        supports are drawn (None: unknown)."""
        try:
            used = [self.prints.get(k) for k in registry.needs(method)]
            # A network's result, and FLARE's, also depends on how supports are drawn.
            used += [supports.DRAW] if registry.resamples(method) else []
        except ValueError:
            return None
        return hashlib.sha256(json.dumps(used).encode()).hexdigest()[:8] if used else "none"

    def current(self, name):
        """Whether the kept file ``name`` (``<scene>__<method>__<tag>.pkl``) is this run's."""
        prefix, _, tag = name[:-len(".pkl")].rpartition("__")
        return name.endswith(".pkl") and tag == self.tag(prefix.rpartition("__")[2])


def kept(workdir, config, bundles: dict) -> int:
    """How many results a run of ``config`` with ``bundles`` would take from ``workdir``
    instead of computing them (0: it starts afresh)."""
    keys = _Keys(config, bundles)
    folder = os.path.join(str(workdir), FOLDER, keys.key)
    return sum(keys.current(n) for n in os.listdir(folder)) if os.path.isdir(folder) else 0


class Finished:
    """The finished results of one evaluation in ``workdir/finished/<key>/``; ``primary``:
    whether this process tidies the other keys' results away (process 0)."""

    def __init__(self, workdir, config, bundles: dict, primary=True):
        self._keys = _Keys(config, bundles)
        self.key = self._keys.key
        # One folder per key: processes of a multi-process run share it without a race, and
        # the results of another config or other bundles are dropped (by process 0 alone).
        root = os.path.join(str(workdir), FOLDER)
        self.folder = os.path.join(root, self.key)
        os.makedirs(self.folder, exist_ok=True)
        if primary:
            for other in os.listdir(root):
                if other != self.key:
                    shutil.rmtree(os.path.join(root, other), ignore_errors=True)
            for name in os.listdir(self.folder):          # results of other bundles
                if not self._keys.current(name):
                    os.remove(os.path.join(self.folder, name))

    def _path(self, method, scene):
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{scene}__{method}__{self._keys.tag(method)}")
        return os.path.join(self.folder, name + ".pkl")

    def get(self, method, scene):
        """The kept result of ``method`` on ``scene``, or None."""
        path = self._path(method, scene)
        if not os.path.isfile(path):
            return None
        with open(path, "rb") as f:
            return pickle.load(f)

    def put(self, result):
        """Keep ``result`` (it has ``method`` and ``scene``); written atomically."""
        files.atomic_write(self._path(result.method, result.scene), pickle.dumps(result))
