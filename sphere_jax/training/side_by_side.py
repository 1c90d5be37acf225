"""Several bundles adapted at once, each in its own process on its own share of the cores.

The networks one method uses (Compass and LEAD for ``lead@compass``) adapt independently, and
much of a training step runs on one core (XLA's loops). Side by side, one core each, each
network made about two thirds of the steps it makes with both cores to itself, where taking
turns leaves each half of them. On the bunny's scans, 10 minutes of wall time on 2 cores:
Compass 955 steps (1501 alone for 10 minutes), LEAD 392 (612); LEAD (Compass)'s inlier ratio
there rose from 0.129 to 0.163 (+26 %), against +29 % with 10 minutes each in turn
(docs/training.md).

Each job pinned to its own core, or both free to use every core (the OS sharing them, so
that the job still running takes both cores once the other stops itself early): on two
bunny pairs, 5 minutes each way, Compass made 250 and 415 steps pinned against 250 and 443
free, LEAD 196 and 173 against 217 and 172 — within the steps' run-to-run spread, so the
jobs stay pinned (``shares``).
"""
from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import threading
import time
import typing

import jax
from tqdm import tqdm

from sphere_jax import checks, compile_cache
from sphere_jax.bundles import model_card, store
from sphere_jax.training import adaptation

POLL_S = 2.0


def usable_cores() -> list[int]:
    """The cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return sorted(os.sched_getaffinity(0))
    return list(range(os.cpu_count() or 1))


def core_shares(n: int, cores=None) -> list[tuple[int, ...]]:
    """``n`` disjoint shares of ``cores`` (default: :func:`usable_cores`), dealt round robin;
    with fewer cores than jobs, every job gets all of them."""
    cores = sorted(usable_cores() if cores is None else cores)
    if len(cores) < n:
        return [tuple(cores)] * n
    return [tuple(cores[i::n]) for i in range(n)]


class _Trained(typing.NamedTuple):
    """What :func:`~sphere_jax.training.adaptation.adapt` reads of a bundle."""
    kind: str
    config: typing.Any
    variables: dict


def exit_with_parent(poll_s=POLL_S):
    """End this process soon after its parent ends. A job whose parent was killed (``kill``,
    out of memory: Ctrl-C reaches the whole process group, a signal to one process does not)
    would go on adapting for its whole budget, into the workdir that rerunning the command
    resumes from, beside the rerun's own job."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(poll_s)
        os._exit(1)            # no cleanup to run: the workdir keeps its last checkpoint

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _adapt_on(cores, bundle_path, data_root, steps, workdir, learning_rate, data, minutes,
              patience, cache_dir=None):
    """One adaptation in a fresh process, pinned to ``cores`` before its first array (XLA's
    CPU client sizes its thread pool by the cores the process may use). ``bundle_path``: a
    bundle folder whose config the caller has read (its weights are read here, once);
    ``cache_dir``: the caller's persistent compilation cache, if any (the next adaptation of
    the same networks then loads its training step instead of compiling it)."""
    exit_with_parent()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, cores)
    if cache_dir:
        compile_cache.enable(cache_dir)
    return adaptation.adapt(_read(bundle_path), data_root, steps, workdir, learning_rate,
                            progress=False, data=data, minutes=minutes, patience=patience)


def _read(bundle_path) -> _Trained:
    config = store.read_config(bundle_path)
    return _Trained(config.model, config, store.read_variables(bundle_path))


def _last_logged(workdir):
    """The last line of ``workdir``'s metrics log as a dict ({} before the first)."""
    try:
        lines = model_card.read_metrics(os.path.join(str(workdir), model_card.METRICS))
    except ValueError:                     # read while the job writes its last line
        return {}
    return lines[-1] if lines else {}


def _watch(futures, names, workdirs, minutes, progress):
    """One progress bar over the wall-time budget, each job's step and loss beside it, until
    every job has ended. The budget's clock starts with the first job's first log line (its
    starting validation loss), as the jobs' own budgets do after reading the scans."""
    total = 60.0 * minutes if minutes else None
    started = None
    with tqdm(total=total, disable=not progress, desc="adapting side by side",
              bar_format="{desc} {percentage:3.0f}%|{bar}|" if total else "{desc}") as bar:
        while not all(f.done() for f in futures):
            concurrent.futures.wait(futures, timeout=POLL_S)
            shown = []
            for name, workdir, future in zip(names, workdirs, futures):
                last = _last_logged(workdir)
                state = ("done" if future.done() else f"step {last['step']}" if last
                         else "reading the scans")
                loss = "".join(f", {label} {last[key]:.4g}" for key, label in
                               (("loss", "loss"), ("val_loss", "validation")) if key in last)
                shown.append(f"{name} {state}{loss}")
                if last and started is None:
                    started = time.perf_counter()
            elapsed = time.perf_counter() - started if started else 0.0
            bar.n = min(elapsed, total) if total else 0
            clock = f"{int(elapsed // 60)}:{int(elapsed % 60):02d}"
            bar.set_description_str(f"adapting side by side, {clock}: " + " | ".join(shown))


def adapt_side_by_side(jobs, data_root, steps=None, minutes=None, learning_rate=None,
                       patience=adaptation.PATIENCE, progress=True, shares=None) -> list[str]:
    """:func:`~sphere_jax.training.adaptation.adapt` for each of ``jobs`` — ``(name, bundle
    folder, workdir, data overrides)`` — at the same time, each in a process of its own on its
    share of the cores (``shares``, default :func:`core_shares`), with the same ``steps`` /
    ``minutes`` budget; a single job adapts in this process, on every core. Returns the
    adapted bundles' paths in the order of ``jobs``; a job that failed raises its error once
    all have ended (the others' bundles are written)."""
    if len(jobs) == 1:
        _, path, workdir, data = jobs[0]
        return [adaptation.adapt(_read(path), data_root, steps, workdir, learning_rate,
                                 progress=progress, data=data, minutes=minutes,
                                 patience=patience)]
    shares = core_shares(len(jobs)) if shares is None else shares
    # spawn: a fresh interpreter per job; a forked JAX runtime is not safe to use.
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(len(jobs), mp_context=context,
                                                max_tasks_per_child=1) as pool:
        cache_dir = jax.config.jax_compilation_cache_dir
        futures = [pool.submit(_adapt_on, share, path, data_root, steps, workdir,
                               learning_rate, data, minutes, patience, cache_dir)
                   for share, (_, path, workdir, data) in zip(shares, jobs)]
        _watch(futures, [j[0] for j in jobs], [j[2] for j in jobs], minutes, progress)
    try:
        return [f.result() for f in futures]
    except concurrent.futures.BrokenExecutor as e:
        # A spawned job first imports the caller's script, which must not start jobs itself.
        raise checks.SphereJaxError(
            "an adaptation job's process ended without a result: killed (out of memory?), or "
            "the calling script adapts side by side outside an `if __name__ == \"__main__\":` "
            "block (each job's process imports the script first, as Python's multiprocessing "
            "does)") from e
