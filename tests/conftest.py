import os
import shutil
import sys
import tempfile

import pytest

from sphere_jax import compile_cache, paths

_XLA_CACHE = "JAX_COMPILATION_CACHE_DIR"
_OWNER = "SPHERE_JAX_TEST_XLA_CACHE_OWNER"


def pytest_configure(config):
    """One persistent XLA compilation cache, inherited by the child processes (the parallel,
    CLI and notebook tests): compiling, not running, is most of the suite's time, and most
    tests build the same small networks in fresh closures. It outlives the run, beside the
    commands' cache (``~/.cache/sphere_jax/xla/<host>-tests``): a rerun compiles only what
    changed (``pytest -m "not slow"`` on 2 cores: 157 s on an empty cache, 107 s warm).
    ``$SPHERE_JAX_COMPILE_CACHE=off`` gives each run a fresh one, removed at its end; an
    existing ``$JAX_COMPILATION_CACHE_DIR`` is kept."""
    if _XLA_CACHE not in os.environ:
        kept = paths.compile_cache_dir()
        if kept:
            os.environ[_XLA_CACHE] = kept + "-tests"
            os.makedirs(os.environ[_XLA_CACHE], mode=0o700, exist_ok=True)
        else:
            os.environ[_XLA_CACHE] = tempfile.mkdtemp(prefix="sphere_jax_xla_")
            # The xdist workers inherit this too: only the process that made it removes it.
            os.environ[_OWNER] = str(os.getpid())
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.1")
    os.environ.setdefault("JAX_COMPILATION_CACHE_MAX_SIZE", str(compile_cache.MAX_BYTES))
    if "jax" in sys.modules:     # imported before us (a plugin): it read the variables already
        jax = sys.modules["jax"]
        jax.config.update("jax_compilation_cache_dir", os.environ[_XLA_CACHE])
        jax.config.update("jax_persistent_cache_min_compile_time_secs",
                          float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))
        jax.config.update("jax_compilation_cache_max_size",
                          int(os.environ["JAX_COMPILATION_CACHE_MAX_SIZE"]))


# The files that take longest (measured one after another: 461, 139, 131, 80, 63, 58 and
# 44 s), run first: workers are handed whole files in collection order (--dist loadfile), and
# one of these left for last kept the other worker idle for minutes.
LONGEST_FIRST = ("tests/test_training.py", "tests/test_parallel.py", "tests/test_notebooks.py",
                 "tests/bundles/test_inference.py", "tests/eval/test_classification.py",
                 "tests/data/generators/test_synthetic.py", "tests/eval/test_ablation.py")


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


def pytest_unconfigure(config):
    if os.environ.get(_OWNER) == str(os.getpid()):
        del os.environ[_OWNER]
        shutil.rmtree(os.environ.pop(_XLA_CACHE), ignore_errors=True)


@pytest.fixture(scope="session")
def shared():
    """Root of the real scans (:func:`sphere_jax.paths.real_data_root`; skips without them)."""
    root = paths.real_data_root()
    if root is None:
        pytest.skip("real data (../shared/data or $SPHERE_JAX_REAL_DATA) not present")
    return root


@pytest.fixture
def unraisable_reports(monkeypatch):
    """What reaches ``sys.unraisablehook`` during the test (call ``gc.collect()`` before
    looking). A corrupt checkpoint must leave none: on CPython 3.11 such reports, printed
    while an AST is being built, crash the interpreter's parser (gh-106905)."""
    reports = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: reports.append(
        f"{type(u.object).__name__}: {u.exc_value!r}"[:200]))
    return reports
