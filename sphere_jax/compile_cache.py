"""A persistent XLA compilation cache, so that a second ``register`` does not compile again.

Compiling the shipped networks costs every new process seconds (``register
--method=lead@compass``: 5.8 of its 56.9 s on 2 cores, docs/performance.md). JAX can keep
compiled programs on disk; :func:`enable` turns that on for this process, in
:func:`sphere_jax.paths.compile_cache_dir` (``~/.cache/sphere_jax/xla/<host>``, one folder per
CPU model and feature set, because XLA:CPU compiles for the host's instruction set; set
``$SPHERE_JAX_COMPILE_CACHE`` to another folder, or to ``off``). The commands in
``experiments/`` call it; a Python user calls it before the first compilation. A cache already
chosen (``$JAX_COMPILATION_CACHE_DIR`` or ``jax.config``) is kept.

The cache is trusted code, like any executable: keep it in a folder only you can write.
"""
from __future__ import annotations

import importlib.util
import os

from sphere_jax import paths

# Older entries are evicted beyond this (JAX keeps the most recently used).
MAX_BYTES = 2 * 1024 ** 3
# Programs that compile faster than this are not worth a file.
MIN_COMPILE_SECONDS = 0.2


def enable(directory=None):
    """Use a persistent compilation cache in ``directory`` (default
    :func:`~sphere_jax.paths.compile_cache_dir`) from the next compilation on. Returns the
    folder in use, or None when the cache is off. Call it before anything is compiled:
    JAX reads the setting once, at its first compilation."""
    import jax
    chosen = jax.config.jax_compilation_cache_dir
    if chosen:
        return chosen
    directory = directory or paths.compile_cache_dir()
    if directory is None:
        return None
    os.makedirs(directory, mode=0o700, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", directory)
    if importlib.util.find_spec("filelock"):     # JAX evicts old entries only with it
        jax.config.update("jax_compilation_cache_max_size", MAX_BYTES)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    return directory
