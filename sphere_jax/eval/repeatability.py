"""LRF repeatability on scan pairs (CONVENTIONS.md §5, §7; seed 3.2).

"Perfect detector": the keypoints of scan i that have a point of scan j within ``match_dist``
under the ground truth correspond to those points. The two frames (j's mapped by the ground
truth rotation) are repeatable if both x̂ and ẑ agree to a dot product ≥ ρ = 0.97; Rep is the
repeatable fraction, averaged over pairs. The mean angle is the geodesic distance between the
two frames. A frame a method could not compute (NaN) counts as not repeatable.
"""
from __future__ import annotations

import dataclasses
import os
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from sphere_jax import models, training
from sphere_jax.bundles import inference, store
from sphere_jax.eval import processes, report, resume, tasks
from sphere_jax.eval import pair_sets as scene_lib
from sphere_jax.features import methods as method_lib
from sphere_jax.features import registry
from sphere_jax.spherical import so3
from sphere_jax.training import adaptation, checkpoints

RHO = 0.97

# How a run that adapts declares it in its title (publish's comparison strips it again).
ADAPTED = ", learned frames adapted on the evaluation scans first"


class FrameCache:
    """Frames of one method per scan, computed once per point whatever the number of pairs
    that ask for it."""

    def __init__(self, orient: Callable):
        self.orient = orient
        self._frames, self._known = {}, {}

    def __call__(self, frag: scene_lib.Fragment, idx):
        idx = np.asarray(idx, np.int64)
        if frag.key not in self._frames:
            self._frames[frag.key] = np.full((len(frag.points), 3, 3), np.nan, np.float32)
            self._known[frag.key] = np.zeros(len(frag.points), bool)
        frames, known = self._frames[frag.key], self._known[frag.key]
        todo = np.unique(idx[~known[idx]])
        if len(todo):
            frames[todo] = np.asarray(self.orient(frag, todo), np.float32).reshape(-1, 3, 3)
            known[todo] = True
        return frames[idx]


def frame_angles_deg(a_Kx3x3, b_Kx3x3):
    """Geodesic angle between corresponding frames, degrees (NaN where either is NaN)."""
    return np.degrees(so3.geodesic_distance_np(a_Kx3x3, b_Kx3x3))


def correspondences(frag_i, frag_j, t_gt, match_dist):
    """Keypoints of i in the overlap and their nearest points of j: ``(idx_i, idx_j)``."""
    inv = np.linalg.inv(t_gt)
    dist, idx = frag_j.tree.query(scene_lib.transform(frag_i.points[frag_i.keypoints], inv), k=1)
    keep = dist[:, 0] < match_dist
    return frag_i.keypoints[keep], idx[keep, 0]


def repeatable(a_x3x3, b_x3x3, rho=RHO):
    """Whether frames (broadcast over leading axes) agree on both x̂ and ẑ to ``rho``; a NaN
    frame never does."""
    with np.errstate(invalid="ignore"):
        return (np.sum(a_x3x3[..., :, 0] * b_x3x3[..., :, 0], -1) >= rho) & \
               (np.sum(a_x3x3[..., :, 2] * b_x3x3[..., :, 2], -1) >= rho)


def pair_repeatability(orient, frag_i, frag_j, t_gt, match_dist, rho=RHO):
    """``orient(fragment, indices) -> [K, 3, 3]``; one pair's keypoints, flags and scores."""
    ki, kj = correspondences(frag_i, frag_j, t_gt, match_dist)
    fi = np.asarray(orient(frag_i, ki), np.float64).reshape(-1, 3, 3)
    fj = t_gt[:3, :3] @ np.asarray(orient(frag_j, kj), np.float64).reshape(-1, 3, 3)
    ok = repeatable(fi, fj, rho)
    angles = frame_angles_deg(fi, fj)
    return {"keypoints": ki, "repeatable": ok, "n": int(len(ki)),
            "rep": float(ok.mean()) if len(ki) else float("nan"),
            "mean_angle_deg": float(np.nanmean(angles)) if np.isfinite(angles).any()
            else float("nan")}


@dataclasses.dataclass
class LrfResult:
    method: str
    scene: str
    pairs: list
    summary: dict


def evaluate_scene(pair_set: scene_lib.PairSet, orienters: dict[str, Callable],
                   prepare_kwargs=None, match_dist=0.02, rho=RHO, seed=0, progress=True,
                   fragments=None, finished=None) -> list[LrfResult]:
    """Every LRF method of ``orienters`` (name -> ``orient(fragment, indices)``) on every pair
    of ``pair_set``; ``fragments`` (key -> :class:`Fragment`, or a function giving them)
    skips the preparation. ``finished`` (:class:`~sphere_jax.eval.resume.Finished`): results
    an interrupted run kept are taken from it, and each new one is kept there as it ends."""
    kept = {name: finished.get(name, pair_set.name) if finished else None
            for name in orienters}
    frags = None
    results = []
    for name, orient in orienters.items():
        if kept[name] is not None:
            results.append(kept[name])
            continue
        if frags is None:
            frags = fragments() if callable(fragments) else fragments or scene_lib.prepare_all(
                pair_set, seed, progress, **(prepare_kwargs or {}))
        cached = FrameCache(orient)
        rows = [dict(pair=(i, j), **pair_repeatability(cached, frags[i], frags[j], t,
                                                        match_dist, rho))
                for (i, j), t in tqdm(pair_set.transforms.items(),
                                      desc=f"{pair_set.name}: {name}", disable=not progress)]
        valid = [r for r in rows if r["n"]]
        mean = lambda key: float(np.nanmean([r[key] for r in valid])) if valid else float("nan")
        results.append(LrfResult(name, pair_set.name, rows,
                                 {"pairs": len(valid), "rep": mean("rep"),
                                  "mean_angle_deg": mean("mean_angle_deg")}))
        if finished is not None:
            finished.put(results[-1])
    return results


# ---- the task ------------------------------------------------------------------------------------

def adapted_bundles(config, bundles, names, workdir, progress):
    """Test-time adaptation of the learned LRF bundles on the evaluation scans, at the
    evaluation's voxel and support radius (keypoints as dense relative to the support as in
    training: the bunny's 1.5 cm supports get keypoints every 5 mm)."""
    out = dict(bundles)
    for kind, spec in models.SPECS.items():
        if spec.orient is not None and kind in names:
            trained = inference.load_bundle(bundles[kind])
            folder = os.path.join(workdir, f"adapted_{kind}")
            _set_aside_if_stale(folder, trained)
            out[kind] = training.adapt(trained, scene_lib.data_root(config),
                                       config.adapt_steps, folder, progress=progress,
                                       data=adaptation.data_at_scale(
                                           trained.config, config.data.voxel, config.data.radius))
    return out


def _set_aside_if_stale(folder, trained):
    """An adaptation in ``folder`` of other weights than ``trained``'s (the bundle was
    retrained since) is this run's own leftover: moved to ``folder-of-<digest>``, kept, so
    that the rerun adapts afresh instead of being refused."""
    old = checkpoints.started_from(folder)
    if os.path.isdir(folder) and old != store.variables_digest(trained.variables):
        aside, n = f"{folder}-of-{old or 'unrecorded'}", 1
        while os.path.exists(aside):
            n += 1
            aside = f"{folder}-of-{old or 'unrecorded'}-{n}"
        os.replace(folder, aside)
        print(f"{folder} adapted other weights than this run's bundle: moved to {aside}")




def run(config, workdir, progress=True):
    """LRF repeatability benchmark: returns ``(rows, markdown)``; writes lrf_results.{csv,md}
    and ``plots/<scene>_<i>_<j>_<method>.png`` in ``workdir`` (scenes split over the
    processes of a ``jax.distributed`` run, :mod:`processes`)."""
    bundles = tasks.bundle_paths(config)
    names = tasks.chosen_methods(config, tuple(registry.LRFS), bundles)
    os.makedirs(workdir, exist_ok=True)
    if config.adapt_steps:
        bundles = adapted_bundles(config, bundles, names, workdir, progress)
    orienters = {m: method_lib.lrf(m, config.data.radius, bundles, config.chunk) for m in names}
    mine, plot_dir = [], os.path.join(workdir, "plots")
    os.makedirs(plot_dir, exist_ok=True)
    finished = resume.Finished(workdir, config, bundles, primary=processes.is_writer())
    for k, s in processes.share(scene_lib.pair_sets(config)):
        frags = {}

        def prepare(s=s, frags=frags):        # only when a method is not finished yet
            frags.update(scene_lib.prepare_all(s, config.seed, progress,
                                               **scene_lib.prepare_kwargs(config)))
            return frags
        scene_results = evaluate_scene(
            s, orienters, match_dist=config.match_dist, rho=config.rho, seed=config.seed,
            progress=progress, fragments=prepare, finished=finished)
        for r in scene_results:
            if not frags:                     # every result was kept: so were its plots
                break
            for row in r.pairs[:config.plot_pairs]:
                i, j = row["pair"]
                report.plot_repeatability(
                    frags[i].points, frags[i].points[row["keypoints"]], row["repeatable"],
                    os.path.join(plot_dir, f"{s.name}_{i}_{j}_{r.method}.png"),
                    f"{r.method}: {s.name} ({i}, {j}), Rep = {row['rep']:.3f}")
        mine.append((k, scene_results))
    results = processes.gather(mine, workdir, "lrf")
    if results is None:                       # another process writes the tables
        return [], ""
    rows = [dict(method=r.method, scene=r.scene, **r.summary) for r in results]
    variant = " (rotated)" if config.rotate else ""
    if config.adapt_steps:          # declared in the title: adapted on the scans it scores
        variant += f"{ADAPTED} ({config.adapt_steps} steps, no ground truth read)"
    md = report.write_tables(workdir, rows, report.LRF_COLUMNS,
                             report.titled(report.LRF_TABLES, rho=config.rho), "lrf_results",
                             f"LRF repeatability{variant}")
    return rows, md


SUMMARY = (("rep", "repeatability", "{:.3f}"), ("mean_angle_deg", "mean angle (°)", "{:.1f}"))


def summary(folder) -> str:
    """A run's published markdown from its files (the workdir or its record in
    docs/records): one table of methods by :data:`SUMMARY`'s metrics."""
    config = tasks.read_record(folder)["config"]
    scenes, means, pairs = report.means_of(folder, "lrf_results")
    variant = " (rotated)" if config.get("rotate") else ""
    if config.get("adapt_steps"):
        variant += f"{ADAPTED} ({config['adapt_steps']} steps, no ground truth read)"
    return (f"# LRF repeatability{variant}\n\n{report.means_table(means, SUMMARY)}\n\n"
            f"Means over {pairs} pairs ({', '.join(scenes)}). Repeatability: share of "
            f"corresponding keypoints whose frames agree (every axis cosine ≥ ρ = "
            f"{config['rho']:g}); mean angle: between corresponding frames.\n")


TASK = tasks.Task(run=run, methods=lambda: tuple(registry.LRFS),
                  check_data=scene_lib.check_data, summary=summary)
