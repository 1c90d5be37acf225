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
    """The finished results of one evaluation in ``workdir/finished/``."""

    def __init__(self, workdir, config, bundles: dict):
        settings = {k: v for k, v in config.to_dict().items() if k != "methods"}
        stamps = {k: [str(p), bundle_files.stamp(p)] for k, p in sorted(bundles.items()) if p}
        text = json.dumps([settings, stamps], sort_keys=True, default=str)
        self.key = hashlib.sha256(text.encode()).hexdigest()[:16]
        self.folder = os.path.join(str(workdir), FOLDER)
        marker = os.path.join(self.folder, "KEY")
        if os.path.isdir(self.folder) and (not os.path.isfile(marker)
                                           or open(marker).read().strip() != self.key):
            shutil.rmtree(self.folder)              # another config or other bundles
        os.makedirs(self.folder, exist_ok=True)
        if not os.path.isfile(marker):
            files.atomic_write(marker, self.key + "\n")

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
