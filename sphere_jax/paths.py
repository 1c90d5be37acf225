"""Where things live, for the library, the configs, the benchmarks and the tests alike.

* the **real scans** with ground truth: ``$SPHERE_JAX_REAL_DATA``, else ``../shared/data``
  beside the checkout (:func:`real_data_root`, :func:`real_data`);
* the **embedded synthetic data** cache: ``$SPHERE_JAX_DATA``, else ``~/.cache/sphere_jax``
  (:func:`cache_root`; what goes in it is :mod:`sphere_jax.data.generators.synthetic`'s);
* the **shipped bundles**: package data in ``sphere_jax/weights/`` (``$SPHERE_JAX_WEIGHTS``
  replaces it; which bundle is which: :mod:`sphere_jax.models.shipped`);
* the **compiled programs** the commands keep (:mod:`sphere_jax.compile_cache`):
  ``$SPHERE_JAX_COMPILE_CACHE``, else ``~/.cache/sphere_jax/xla/<host>``
  (:func:`compile_cache_dir`).
"""
from __future__ import annotations

import hashlib
import os
import platform


REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def real_data_root():
    """The folder of the real scans (it holds ``3dmatch/``), or None when there is none.
    A set ``$SPHERE_JAX_REAL_DATA`` is the only place looked at: empty, it stands for a fresh
    clone without the scans (how the tests' embedded fallbacks are checked)."""
    if "SPHERE_JAX_REAL_DATA" in os.environ:
        candidates = (os.environ["SPHERE_JAX_REAL_DATA"],)
    else:
        candidates = (os.path.join(REPO, "..", "shared", "data"),
                      os.path.join(os.getcwd(), "..", "..", "shared", "data"))  # notebooks/
    for root in candidates:
        if root and os.path.isdir(os.path.join(root, "3dmatch")):
            return os.path.normpath(root)
    return None


def real_data(*parts):
    """A path inside the real scans, or None when they are absent (the path itself may not
    exist: callers check, as for any partial download)."""
    root = real_data_root()
    return os.path.join(root, *parts) if root else None


def cache_root():
    return os.environ.get("SPHERE_JAX_DATA",
                          os.path.join(os.path.expanduser("~"), ".cache", "sphere_jax"))


def compile_cache_dir():
    """Where compiled XLA programs are kept: ``$SPHERE_JAX_COMPILE_CACHE`` (``off`` or empty:
    nowhere, None), else ``~/.cache/sphere_jax/xla/<host>``. XLA:CPU compiles for the CPU it
    runs on, so ``<host>`` names the CPU model and its instruction-set flags: machines that
    share a home folder never run each other's programs."""
    chosen = os.environ.get("SPHERE_JAX_COMPILE_CACHE")
    if chosen is not None:
        return None if chosen.strip().lower() in ("", "off", "0", "none") else chosen
    return os.path.join(os.path.expanduser("~"), ".cache", "sphere_jax", "xla", _host_key())


def _host_key():
    cpu = platform.machine() + platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            lines = [ln for ln in f if ln.startswith(("model name", "flags", "Features"))]
        cpu += "".join(sorted(set(lines)))
    except OSError:                        # not Linux: the platform's description only
        pass
    return hashlib.sha256(cpu.encode()).hexdigest()[:12]


def weights_root():
    """The shipped bundles: package data (``sphere_jax/weights``), so that any install —
    editable, ``pip install .``, a wheel — has them; ``$SPHERE_JAX_WEIGHTS`` replaces it."""
    return os.path.normpath(os.environ.get("SPHERE_JAX_WEIGHTS")
                            or os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                            "weights"))


def relative(path) -> str:
    """``path`` relative to the checkout's root (``../shared/data``) for what notebooks and
    messages show: no machine's absolute path."""
    return os.path.relpath(os.path.abspath(str(path)), REPO)


def portable(path):
    """``path`` as a label that means the same on any machine: ``embedded/<rel>`` under the
    synthetic data cache, ``shared/<rel>`` under the real scans, else the absolute path."""
    path = os.path.abspath(str(path))
    for label, root in (("embedded", cache_root()), ("shared", real_data_root())):
        if root and os.path.commonpath([path, os.path.abspath(root)]) == os.path.abspath(root):
            return "/".join([label, os.path.relpath(path, root).replace(os.sep, "/")])
    return path
