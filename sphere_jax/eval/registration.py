"""Descriptor matching and registration on fragment pairs (CONVENTIONS.md §7; seed 4.3).

For each pair (i, j) with ground truth ``p_i = T p_j``:

* mutual nearest neighbours in descriptor space (:mod:`sphere_jax.registration`, as
  ``sphere_jax.register`` matches);
* a match is correct if ``‖p_i − T p_j‖ < τ1`` (0.10 m); inlier ratio = correct / matches;
  the pair counts towards feature-match recall if its inlier ratio exceeds ``τ2`` (5 %);
* RANSAC (open3d) on the matches estimates ``T̂``; ``RRE = arccos((tr(R̂ᵀR) − 1)/2)``,
  ``RTE = ‖t̂ − t‖``; a pair is registered if RRE < 15° and RTE is below one support radius
  (0.3 m at 3DMatch's 0.30 m: the usual registration-recall thresholds; 1.5 cm at the
  bunny's 1.5 cm supports).

Per scene: FMR, mean inlier ratio, mean number of correct matches, registration recall, and
RRE / RTE averaged over the registered pairs (over all pairs they would only measure failures).
"""
from __future__ import annotations

import dataclasses
import functools
import os
from typing import Callable

import jax
import numpy as np
from tqdm.auto import tqdm

from sphere_jax.eval import processes, report, resume, tasks, timing
from sphere_jax.eval import pair_sets as scene_lib
from sphere_jax.features import methods as method_lib
from sphere_jax.features import registry
from sphere_jax.registration.estimation import SCREEN_ITERATIONS, consensus, ransac
from sphere_jax.registration.matching import mutual_matches
from sphere_jax.registration.vote import HYPOTHESES, VotedFrames
from sphere_jax.spherical import so3


TAU1, TAU2 = 0.10, 0.05
RRE_OK_DEG, RTE_OK_M = 15.0, 0.30      # RTE_OK_M: 3DMatch's; runs pass their support radius


def rre_rte(t_est, t_gt):
    """Relative rotation error (degrees) and translation error (same unit as t)."""
    rre = np.degrees(so3.geodesic_distance_np(t_est[:3, :3], t_gt[:3, :3]))
    return float(rre), float(np.linalg.norm(t_est[:3, 3] - t_gt[:3, 3]))


def registered(rre_deg, rte, rte_ok=RTE_OK_M) -> bool:
    """Whether an estimate with these errors registers the pair."""
    return bool(rre_deg < RRE_OK_DEG and rte < rte_ok)


def match_pair(frag_i, frag_j, desc_i, desc_j, t_gt, tau1=TAU1, ransac_distance=0.05,
               ransac_iterations=50_000, seed=0, rte_ok=RTE_OK_M):
    """Metrics of one pair; ``errors`` (distance of every match under the ground truth) lets
    callers recompute recall for any τ1/τ2."""
    ia, ib = mutual_matches(desc_i, desc_j)
    pi = frag_i.points[frag_i.keypoints[ia]]
    pj = frag_j.points[frag_j.keypoints[ib]]
    errors = np.linalg.norm(pi - scene_lib.transform(pj, t_gt), axis=1)
    correct = errors < tau1
    t_est = ransac(pi, pj, ransac_distance, ransac_iterations, seed)
    rre, rte = rre_rte(t_est, t_gt)
    return {"matches": int(len(ia)), "n_correct": int(correct.sum()),
            "inlier_ratio": float(correct.mean()) if len(ia) else 0.0,
            "rre_deg": rre, "rte_m": rte,
            "registered": registered(rre, rte, rte_ok),
            "errors": errors, "t_est": t_est}


def feature_match_recall(pair_rows, tau1=TAU1, tau2=TAU2):
    """Fraction of pairs whose share of matches within ``tau1`` exceeds ``tau2``."""
    if not pair_rows:
        return float("nan")
    ok = [np.mean(r["errors"] < tau1) > tau2 if len(r["errors"]) else False for r in pair_rows]
    return float(np.mean(ok))


def summarise(pair_rows, tau1=TAU1, tau2=TAU2, rte_ok=RTE_OK_M):
    """Scene-level numbers from :func:`match_pair` rows."""
    reg = [r for r in pair_rows if registered(r["rre_deg"], r["rte_m"], rte_ok)]
    mean = lambda key, rows: float(np.mean([r[key] for r in rows])) if rows else float("nan")
    return {"pairs": len(pair_rows), "fmr": feature_match_recall(pair_rows, tau1, tau2),
            "inlier_ratio": mean("inlier_ratio", pair_rows),
            "n_correct": mean("n_correct", pair_rows),
            "rr": float(len(reg) / len(pair_rows)) if pair_rows else float("nan"),
            "rre_deg": mean("rre_deg", reg), "rte_m": mean("rte_m", reg)}


@dataclasses.dataclass
class SceneResult:
    """One method on one scene: per-pair rows, the summary and the description time."""
    method: str
    scene: str
    pairs: list
    summary: dict
    ms_per_keypoint: float
    others_cpu: float | None = None    # the cores' share other processes used (timing.py)


def evaluate_scene(pair_set: scene_lib.PairSet, describers: dict[str, Callable],
                   prepare_kwargs=None, tau1=TAU1, tau2=TAU2, ransac_distance=0.05,
                   ransac_iterations=50_000, seed=0, progress=True,
                   finished=None, rte_ok=RTE_OK_M) -> list[SceneResult]:
    """Every method of ``describers`` (name -> ``describe(fragment) -> [K, D]``, a
    :class:`~sphere_jax.features.methods.GroundTruthFrames` or a
    :class:`~sphere_jax.registration.vote.VotedFrames`) on every pair of ``pair_set``, on the same
    prepared fragments and keypoints. A voted method's rows add ``vote_rre_deg`` (the voted
    rotation's error), ``vote_support`` and ``vote_proposals`` (the first-pass matches that
    agreed with it, and all of them), ``vote_mode`` and ``box_turn_deg`` (which of the vote's
    modes the consensus kept, 0 the strongest, and the box turn applied to it) and
    ``second_pass`` (False where RANSAC's consensus kept the first pass). ``finished``
    (:class:`~sphere_jax.eval.resume.Finished`): results kept by an earlier, interrupted run
    are taken from it, and each new one is kept there as it ends; their summaries are
    recomputed, so they follow this code's thresholds."""
    kept = {name: finished.get(name, pair_set.name) if finished else None
            for name in describers}
    kept = {name: r if r is None else dataclasses.replace(
        r, summary=summarise(r.pairs, tau1, tau2, rte_ok)) for name, r in kept.items()}
    if all(r is not None for r in kept.values()):
        return list(kept.values())
    frags = scene_lib.prepare_all(pair_set, seed, progress, **(prepare_kwargs or {}))
    agree = functools.partial(consensus, max_distance=ransac_distance,
                              iterations=ransac_iterations, seed=seed)
    screen = functools.partial(agree, iterations=min(ransac_iterations, SCREEN_ITERATIONS))
    results = []
    for name, describe in describers.items():
        if kept[name] is not None:
            results.append(kept[name])
            continue
        with timing.Stopwatch() as watch:
            inputs, n_described, votes = _pair_descriptors(name, describe, frags, pair_set,
                                                           progress, agree, screen)
        ms = 1000.0 * watch.seconds / max(n_described, 1)
        rows = [dict(pair=(i, j), **match_pair(frags[i], frags[j], *inputs[(i, j)], t, tau1,
                                               ransac_distance, ransac_iterations, seed,
                                               rte_ok),
                     **_vote_row(votes.get((i, j)), t))
                for (i, j), t in pair_set.transforms.items()]
        results.append(SceneResult(name, pair_set.name, rows,
                                   summarise(rows, tau1, tau2, rte_ok), ms, watch.others))
        if finished is not None:
            finished.put(results[-1])
    return results


def _vote_row(vote, t_gt):
    if vote is None:
        return {}
    return {"vote_rre_deg": float(np.degrees(so3.geodesic_distance_np(vote.rotation,
                                                                       t_gt[:3, :3]))),
            "vote_support": vote.support, "vote_proposals": vote.proposals,
            "second_pass": vote.second_pass, "vote_mode": vote.mode,
            "box_turn_deg": vote.box_turn_deg}


def _pair_descriptors(name, describe, frags, pair_set, progress, agree=None, screen=None):
    """``({(i, j): (desc_i, desc_j)}, keypoints described, {(i, j): Vote})``: each scan
    described once, or, for a ground-truth diagnostic (``describe.describe_pair``), both scans
    of every pair in that pair's frames, or, for a voted method, in the frames its first pass
    voted (``screen`` ranks the vote's candidates, the pass ``agree`` scores higher is kept). Wrong
    counts and non-finite values are refused, naming the method."""
    describe_pair = getattr(describe, "describe_pair", None)
    bar = lambda items: tqdm(items, desc=f"{pair_set.name}: {name}", disable=not progress)
    votes = {}
    if isinstance(describe, VotedFrames):
        inputs, votes = describe.describe_pairs(frags, pair_set.transforms, mutual_matches,
                                                agree, bar, screen)
        inputs = {p: tuple(np.asarray(d, np.float32) for d in pair) for p, pair in
                  inputs.items()}
        n_described = sum(len(f.keypoints) for f in frags.values())
    elif describe_pair is None:
        desc = {k: np.asarray(describe(f), np.float32) for k, f in bar(frags.items())}
        inputs = {(i, j): (desc[i], desc[j]) for i, j in pair_set.transforms}
        n_described = sum(len(f.keypoints) for f in frags.values())
    else:
        inputs = {(i, j): tuple(np.asarray(d, np.float32)
                                for d in describe_pair(frags[i], frags[j], t))
                  for (i, j), t in bar(pair_set.transforms.items())}
        n_described = sum(len(frags[i].keypoints) + len(frags[j].keypoints) for i, j in inputs)
    for (i, j), pair in inputs.items():
        for k, d in zip((i, j), pair):
            finite = np.isfinite(d)
            # a row all NaN is an undescribed keypoint (it never matches); part of one is a bug
            if d.shape[0] != len(frags[k].keypoints) or \
                    not np.all(finite.all(1) | np.isnan(d).all(1)):
                raise ValueError(f"method {name!r} returned {d.shape} descriptors with "
                                 f"non-finite values or a wrong count for scan {k}")
    return inputs, n_described, votes


VOTE_COLUMNS = ("method", "scene", "pair", "vote_rre_deg", "vote_support", "vote_proposals",
                "vote_mode", "box_turn_deg", "second_pass")


def _write_votes(workdir, results, variant):
    """votes.{csv,md}: per pair, how far each voted method's rotation is from the truth."""
    rows = [dict(method=r.method, scene=r.scene, pair=f"{p['pair'][0]}-{p['pair'][1]}",
                 **{k: p[k] for k in VOTE_COLUMNS[3:]})
            for r in results for p in r.pairs if "vote_rre_deg" in p]
    if rows:
        report.write(workdir, "votes", rows, VOTE_COLUMNS,
                     f"# Pair votes{variant}\n\nThe voted rotation's error against the "
                     f"ground truth (°), how many of the first pass's proposals (one per "
                     f"match) agreed with it, which of the vote's modes it is (0: the "
                     f"strongest), the box turn applied to it (0: none; RANSAC's consensus "
                     f"chose both) and whether the second pass "
                     f"was kept (False: RANSAC found more inliers among the first pass's "
                     f"matches).\n\n"
                     + report.table(rows, VOTE_COLUMNS, fmt="{:.2f}") + "\n")


def fmr_curve(results: list[SceneResult], tau2_values, tau1=TAU1):
    """``{method: [FMR averaged over scenes at each τ2]}`` (the seed's recall-vs-τ2 plot)."""
    out = {}
    for method in dict.fromkeys(r.method for r in results):
        per_scene = [r for r in results if r.method == method]
        out[method] = [float(np.mean([feature_match_recall(r.pairs, tau1, t2)
                                      for r in per_scene])) for t2 in tau2_values]
    return out


# ---- the task ------------------------------------------------------------------------------------

def _describer(name, config, bundles):
    radius, chunk = config.data.radius, config.chunk
    kind = registry.resolve(name).kind
    if kind == "diagnostic":
        return method_lib.ground_truth_frames(name, radius, bundles, chunk)
    if kind == "voted":
        return method_lib.voted_frames(name, radius, bundles, chunk,
                                  hypotheses=config.get("vote_hypotheses", HYPOTHESES),
                                  box=config.get("vote_box", True))
    return method_lib.descriptor(name, radius, bundles, config.fpfh_radius, chunk)




def run(config, workdir, progress=True):
    """Descriptor benchmark: returns ``(rows, markdown)``; writes results.{csv,md} and
    fmr_vs_tau2.png in ``workdir``. Under ``jax.distributed`` the scenes are split over the
    processes and process 0 writes the tables (:mod:`processes`)."""
    bundles = tasks.bundle_paths(config)
    names = tasks.chosen_methods(config, registry.keys(), bundles)
    describers = {m: _describer(m, config, bundles) for m in names}
    finished = resume.Finished(workdir, config, bundles, primary=jax.process_index() == 0)
    mine = [(k, evaluate_scene(s, describers, scene_lib.prepare_kwargs(config), config.tau1,
                               config.tau2, config.ransac_distance, config.ransac_iterations,
                               config.seed, progress, finished, rte_ok=config.data.radius))
            for k, s in processes.share(scene_lib.pair_sets(config))]
    results = processes.gather(mine, workdir, "registration")
    if results is None:                       # another process writes the tables
        return [], ""
    # A result kept before others_cpu existed reads the field's default, None: "not recorded".
    rows = [dict(method=r.method, scene=r.scene, ms_per_keypoint=r.ms_per_keypoint,
                 others_cpu=float("nan") if r.others_cpu is None else r.others_cpu,
                 **r.summary) for r in results]
    os.makedirs(workdir, exist_ok=True)
    variant = " (rotated)" if config.rotate else ""
    tables = report.titled(report.REGISTRATION_TABLES, tau1=config.tau1, tau2=config.tau2,
                           rre=RRE_OK_DEG, rte=config.data.radius)
    md = report.write_tables(workdir, rows, report.REGISTRATION_COLUMNS, tables, "results",
                             f"Registration benchmark{variant}")
    _write_votes(workdir, results, variant)
    curve = fmr_curve(results, config.tau2_curve, config.tau1)
    report.plot_fmr_curve(curve, config.tau2_curve, os.path.join(workdir, "fmr_vs_tau2.png"),
                          f"Feature-match recall vs τ2{variant}")
    return rows, md


# The published table of a run (docs/results.md, the model cards): means over its pairs.
SUMMARY = (("fmr", "FMR", "{:.3f}"), ("inlier_ratio", "inlier ratio", "{:.3f}"),
           ("n_correct", "correct / pair", "{:.0f}"), ("rr", "RR", "{:.2f}"),
           ("rre_deg", "RRE (°)", "{:.2f}"), ("rte_m", "RTE (m)", "{:.3f}"),
           ("ms_per_keypoint", "ms / keypoint", "{:.2f}"))


def summary(folder) -> str:
    """A run's published markdown from its files (``folder``: the workdir or its record in
    docs/records): one table of methods by :data:`SUMMARY`'s metrics, and the pair votes'
    accuracy where voted methods ran."""
    config = tasks.read_record(folder)["config"]
    scenes, means, pairs = report.means_of(folder, "results")
    out = [f"# Registration benchmark{' (rotated)' if config.get('rotate') else ''}", "",
           report.means_table(means, SUMMARY), "",
           f"Means over {pairs} pairs ({', '.join(scenes)}). FMR: share of pairs with an "
           f"inlier ratio ≥ τ2 = {config['tau2']:g} at τ1 = {config['tau1']:g} m. RR: RANSAC "
           f"results within RRE < {RRE_OK_DEG:g}° and RTE < {config['data']['radius']:g} m; "
           f"RRE and RTE: means over those. ms / keypoint: description time."]
    votes = report.read_rows(folder, "votes")
    if votes:
        out += ["", "| voted method | pairs | vote RRE median (°) | vote RRE max (°) | "
                "second pass kept |", "|---|---|---|---|---|"]
        for method in dict.fromkeys(v["method"] for v in votes):
            mine = [v for v in votes if v["method"] == method]
            rre = np.array([float(v["vote_rre_deg"]) for v in mine])
            kept = sum(v["second_pass"] == "True" for v in mine)
            out.append(f"| {method} | {len(mine)} | {np.median(rre):.2f} | {rre.max():.2f} | "
                       f"{kept} |")
        out += ["", "The pair vote's rotation against the ground truth, before RANSAC; "
                "second pass kept: RANSAC found more inliers among its matches than among "
                "the first pass's."]
    return "\n".join(out) + "\n"


TASK = tasks.Task(run=run, methods=registry.keys, check_data=scene_lib.check_data,
                  summary=summary)
