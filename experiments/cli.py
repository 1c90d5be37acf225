"""What the mains share: config names, bad input as one line on stderr, and a persistent
compilation cache (:mod:`sphere_jax.compile_cache`: a second run does not compile again).

A bad flag, an unknown config, an unknown config field or a value the run cannot use is one
line (``train: error: ...``) and exit status 2, before any work starts; another refusal of
the project's (:class:`sphere_jax.SphereJaxError`: a corrupt file, a non-finite loss) is one
line and status 1; Ctrl-C is one line and status 130. Anything else is a bug and keeps its
traceback.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import re
import shlex
import sys

from absl import app, flags

from configs import resolve_config_arg
from sphere_jax import checks, compile_cache

USAGE = 2
INTERRUPTED = 130


def _main_name() -> str:
    """The running main's module name (``train`` for ``python -m experiments.train``)."""
    name = os.path.splitext(os.path.basename(sys.argv[0]))[0]
    return {"__main__": "experiments"}.get(name, name)


def fail(message, status=USAGE):
    prog = _main_name()
    first = str(message).strip().splitlines()
    print(f"{prog}: error: {' '.join(line.strip() for line in first)}", file=sys.stderr)
    sys.exit(status)


_ARGV = []        # the command line as typed (run() resolves config names in sys.argv)


def command(module):
    """The command line that started this main, as typed: ``python -m MODULE ARGS``."""
    args = (_ARGV or sys.argv)[1:]
    return " ".join(["python -m", module] + [shlex.quote(a) for a in args])


def run(main):
    """``app.run(main)`` with config names resolved, errors as one line and compiled programs
    kept on disk (:mod:`sphere_jax.compile_cache`)."""
    _ARGV[:] = sys.argv
    compile_cache.enable()
    try:
        sys.argv = resolve_config_arg(sys.argv)
        specs = [a.split("=", 1)[1] for a in sys.argv if a.startswith("--config=")]
        if specs:
            spec = specs[-1]                         # absl keeps the last
            load_config(spec, strict=True)       # a bad size: our message, not absl's dump
    except checks.SphereJaxError as e:
        fail(e)
    app.run(_guarded(main), flags_parser=_parse)


@contextlib.contextmanager
def refusals(arguments=False):
    """The project's refusals inside as one line: bad usage, input or config values exit 2,
    any other :class:`~sphere_jax.SphereJaxError` 1 (the argparse mains use it directly), and
    Ctrl-C one line and 130 (the shell's status for SIGINT).
    ``arguments``: the block only reads what the command line names (bundles, scans, files),
    so every refusal there is the command line's: exit 2."""
    try:
        yield
    except (app.UsageError, checks.ConfigError, checks.InputError) as e:
        fail(e)
    except checks.SphereJaxError as e:
        fail(e, USAGE if arguments else 1)
    except KeyboardInterrupt:
        # What was saved stays saved; the resuming mains go on from it.
        print(f"{_main_name()}: interrupted (train, evaluate and adapt go on from their last "
              f"checkpoint or result when the same command runs again)", file=sys.stderr)
        sys.exit(INTERRUPTED)


def _number(parse, ok, what):
    """An argparse type: ``parse(text)`` when ``ok`` of it, else the flag's one-line refusal
    (``argument --keypoints: expected a positive integer, got '-3'``)."""
    def typed(text):
        try:
            value = parse(text)
        except ValueError:
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value
    return typed


positive_int = _number(int, lambda v: v > 0, "a positive integer")
non_negative_int = _number(int, lambda v: v >= 0, "a non-negative integer")
positive_number = _number(float, lambda v: 0 < v < float("inf"), "a positive number")
fraction = _number(float, lambda v: 0 <= v <= 1, "a number in [0, 1]")
# ``--voxel`` and ``--radius``: ``auto`` or a positive number.
scale = _number(lambda t: t if t == "auto" else float(t),
                lambda v: v == "auto" or 0 < v < float("inf"), "'auto' or a positive number")


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose refusals are one line on stderr with exit status 2, like the absl mains'
    (argparse's own print the usage first). ``doc``: the main's docstring, whose first
    paragraph becomes ``--help``'s description; the usage line names the command as it is
    typed (``python -m experiments.NAME``), not the file."""

    def __init__(self, *args, doc=None, **kwargs):
        if doc is not None:
            kwargs.setdefault("description", " ".join(doc.split("\n\n")[0].split()))
        if os.path.basename(os.path.dirname(os.path.abspath(sys.argv[0]))) == "experiments":
            kwargs.setdefault("prog", f"python -m experiments.{_main_name()}")
        super().__init__(*args, **kwargs)

    def error(self, message):
        fail(message)

    def parse_known_args(self, args=None, namespace=None):
        parsed = super().parse_known_args(args, namespace)
        # Every argparse main parses before it computes: keep its compiled programs on disk.
        compile_cache.enable()
        return parsed


def _guarded(main):
    def guarded(argv):
        with refusals():
            return main(argv)
    return guarded


def _parse(argv):
    try:
        return flags.FLAGS(argv)
    except Exception as e:                   # absl's flags.Error or ml_collections' errors
        fail(explain_override(argv) or _flag_message(e))


def _flag_message(error):
    text = str(error).strip().splitlines()
    lines = [ln.strip() for ln in text if ln.strip() and not ln.startswith("  File")]
    return lines[0] if lines else type(error).__name__


def explain_override(argv):
    """For a ``--config.a.b=v`` naming a field the config lacks: the message listing the
    fields of the deepest section that exists (None when every override names a field)."""
    specs = [a.split("=", 1)[1] for a in argv if a.startswith("--config=")]
    config = load_config(specs[-1]) if specs else None
    if config is None:
        return None
    for a in argv:
        m = re.match(r"--config\.([A-Za-z0-9_.]+)(=|$)", a)
        if not m:
            continue
        node, path = config, "config"
        for part in m.group(1).split("."):
            if not hasattr(node, "keys") or part not in node:
                fields = ", ".join(sorted(node.keys())) if hasattr(node, "keys") else "none"
                return (f"unknown field {path}.{part} in --config.{m.group(1)}; the fields of "
                        f"{path} are: {fields}")
            node, path = node[part], f"{path}.{part}"
    return None


def load_config(spec, strict=False):
    """The config of ``--config=PATH[:ARG]``; None when it does not load (absl then says
    why), except that ``strict`` lets the project's own errors through."""
    path, _, arg = spec.partition(":")
    try:
        module_spec = importlib.util.spec_from_file_location("_config", path)
        module = importlib.util.module_from_spec(module_spec)
        module_spec.loader.exec_module(module)
        return module.get_config(arg or None)
    except checks.SphereJaxError:
        if strict:
            raise
        return None
    except Exception:
        return None


