"""Evaluations that resume: each finished (method, scene) result is kept in the workdir as it
ends, and the same command after a kill redoes only what was not finished.

The results are keyed by everything that decides them — the evaluation config (without its
method list: each method's result stands alone) and the bundles' files — so a changed config
or a retrained bundle starts afresh instead of mixing old and new results.
"""
from __future__ import annotations

import hashlib
import json
import os
import pickle
import re
import shutil

from sphere_jax import bundle as bundle_files
from sphere_jax import files

FOLDER = "finished"


class Finished:
    """The finished results of one evaluation in ``workdir/finished/<key>/``; ``primary``:
    whether this process tidies the other keys' results away (process 0)."""

    def __init__(self, workdir, config, bundles: dict, primary=True):
        settings = {k: v for k, v in config.to_dict().items() if k != "methods"}
        stamps = {k: [str(p), bundle_files.stamp(p)] for k, p in sorted(bundles.items()) if p}
        text = json.dumps([settings, stamps], sort_keys=True, default=str)
        self.key = hashlib.sha256(text.encode()).hexdigest()[:16]
        # One folder per key: processes of a multi-process run share it without a race, and
        # the results of another config or other bundles are dropped (by process 0 alone).
        root = os.path.join(str(workdir), FOLDER)
        self.folder = os.path.join(root, self.key)
        os.makedirs(self.folder, exist_ok=True)
        if primary:
            for other in os.listdir(root):
                if other != self.key:
                    shutil.rmtree(os.path.join(root, other), ignore_errors=True)

    def _path(self, method, scene):
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{scene}__{method}")
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
