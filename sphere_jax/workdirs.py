"""One run per workdir, and workdirs that cannot be used refused before any work.

``with claimed(workdir, command):`` creates the folder (a clear error when it cannot be
created or written) and holds an exclusive lock on ``workdir/.lock`` for the run
(``fcntl.flock``: the kernel releases it when the process ends, however it ends, so a lock is
never stale). A second run on the same workdir — a typo, a scheduler's retry — is refused at
once with the first one's process id, host, command and start time. In a multi-process run
only process 0 locks (the others share its workdir by design).
"""
from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import os
import socket

from sphere_jax import checks

LOCK = ".lock"
_HELD = {}          # real path -> open lock file: a run that claims its own workdir again


class WorkdirBusy(checks.ConfigError):
    """Another run holds the workdir."""


def prepare(workdir, flag="--workdir") -> str:
    """Create ``workdir`` if needed; ConfigError (naming ``flag``) when it cannot be created
    or written."""
    workdir = str(workdir)
    try:
        os.makedirs(workdir, exist_ok=True)
    except OSError as e:
        raise checks.ConfigError(f"{flag} {workdir} cannot be created: "
                                 f"{e.strerror or e} ({e.filename or workdir})") from None
    if not os.access(workdir, os.W_OK | os.X_OK):
        raise checks.ConfigError(f"{flag} {workdir} cannot be written (permission denied)")
    return workdir


@contextlib.contextmanager
def claimed(workdir, command=None, primary=True):
    """Hold ``workdir`` for this run (see the module); ``primary``: whether this process takes
    the lock (process 0 of a multi-process run)."""
    workdir = prepare(workdir)
    key = os.path.realpath(workdir)
    if not primary or key in _HELD:
        yield workdir
        return
    path = os.path.join(workdir, LOCK)
    try:
        f = open(path, "a+")
    except OSError as e:
        raise checks.ConfigError(f"--workdir {workdir} cannot be written: {e.strerror}") from None
    try:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.seek(0)
        holder = _holder(f.read())
        f.close()
        raise WorkdirBusy(f"--workdir {workdir} is in use by {holder}; wait for that run to "
                          f"end or choose another workdir") from None
    f.seek(0)
    f.truncate()
    f.write(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                        "command": command or "", "since": datetime.datetime.now()
                        .isoformat(timespec="seconds")}))
    f.flush()
    _HELD[key] = f
    try:
        yield workdir
    finally:
        del _HELD[key]
        fcntl.flock(f.fileno(), fcntl.LOCK_UN)
        f.close()


def _holder(text):
    try:
        h = json.loads(text)
        what = f" ({h['command']})" if h.get("command") else ""
        return f"process {h['pid']} on {h['host']}{what}, running since {h['since']}"
    except (ValueError, KeyError, TypeError):
        return "another process"
