import pytest

from sphere_jax import paths


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
    import sys
    reports = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: reports.append(
        f"{type(u.object).__name__}: {u.exc_value!r}"[:200]))
    return reports
