"""Writing files so that a reader finds the old one or the new one, never half of either.

Everything the project writes that another run reads back — bundles, tables, metrics, model
cards, generated data — goes through :func:`atomic_write` or :func:`replacing`: the content is
written under a temporary name in the same folder, flushed to disk, and renamed over the
target (one atomic step on POSIX). A full disk or a kill mid-write leaves the previous file
(and at most a temporary one, removed when the error is seen).
"""
from __future__ import annotations

import contextlib
import os
import shutil


def _tmp_name(path, suffix=""):
    head, tail = os.path.split(os.path.abspath(str(path)))
    return os.path.join(head, f".{tail}.tmp{os.getpid()}{suffix}")


@contextlib.contextmanager
def replacing(path, suffix=""):
    """``with replacing(path) as tmp:`` write the file ``tmp``; on success it replaces
    ``path``, on an error it is removed and ``path`` is untouched. ``suffix``: for writers
    that choose a format by extension (``.png``)."""
    tmp = _tmp_name(path, suffix)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        _remove(tmp)
        raise


def atomic_write(path, data):
    """Write ``data`` (bytes or str) to ``path`` atomically."""
    mode = "wb" if isinstance(data, (bytes, bytearray)) else "w"
    with replacing(path) as tmp:
        with open(tmp, mode) as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())


def swap_folders(new, path):
    """Replace folder ``path`` by folder ``new``: the old one is renamed aside first and
    removed only once the new one is in place."""
    old = _tmp_name(path, ".old")
    os.replace(path, old)
    try:
        os.replace(new, path)
    except BaseException:
        os.replace(old, path)
        raise
    _remove(old)


def _remove(path):
    if os.path.isdir(path):
        shutil.rmtree(path, ignore_errors=True)
    elif os.path.lexists(path):
        with contextlib.suppress(OSError):
            os.remove(path)
