"""The registration and LRF benchmarks end to end, from an evaluation config
(``configs/eval_registration.py``, ``configs/eval_lrf.py``): find the scans, prepare them once,
run every method on the same keypoints, write tables and plots. ``experiments.evaluate`` is a
thin main over :func:`run`; notebooks call the same functions.
"""
from __future__ import annotations

import json
import os
import warnings

from sphere_jax.eval import methods as method_lib
from sphere_jax.eval import registration, repeatability, report, scenes as scene_lib


def data_root(config):
    if config.data.root:
        return config.data.root
    from sphere_jax.data import pipeline
    return pipeline.default_scan_root()


def pair_sets(config):
    """The scan sets of ``config.data`` (scene filter, pair limit, rotated variant applied)."""
    sets = scene_lib.find_pair_sets(data_root(config), config.data.voxel,
                                    config.data.get("min_overlap", 0.10))
    if config.data.scenes:
        wanted = [s.strip() for s in config.data.scenes.split(",") if s.strip()]
        unknown = sorted(set(wanted) - {s.name for s in sets})
        if unknown:
            raise ValueError(f"data.scenes names {unknown} not among "
                             f"{[s.name for s in sets]}")
        sets = [s for s in sets if s.name in wanted]
    out = []
    for s in sets:
        if config.data.max_pairs:
            s.transforms = {p: s.transforms[p] for p in s.pairs[:config.data.max_pairs]}
        if not s.transforms:
            warnings.warn(f"{s.name}: no pairs with ground truth; skipped", stacklevel=2)
            continue
        out.append(scene_lib.rotate(s, config.seed)[0] if config.rotate else s)
    if not out:
        raise ValueError(f"no scan pairs with ground truth under {data_root(config)!r}")
    return out


def bundle_paths(config):
    """Kind -> bundle path: the config's defaults, ``config.bundle`` replacing its kind's."""
    paths = dict(config.bundles.to_dict())
    if config.bundle:
        cfg = os.path.join(config.bundle, "config.json")
        if not os.path.isfile(cfg):
            raise FileNotFoundError(f"bundle={config.bundle!r} is not a bundle (no config.json)")
        with open(cfg) as f:
            paths[json.load(f)["model"]] = config.bundle
    return paths


def chosen_methods(config, known, bundles):
    names = [m.strip() for m in config.methods.split(",") if m.strip()]
    bad = [m for m in names if m not in known]
    if bad:
        raise ValueError(f"methods {bad} unknown; choose from {', '.join(known)}")
    missing = method_lib.bundles_needed(names, bundles)
    for m in missing:
        warnings.warn(f"method {m!r} skipped: no bundle for {method_lib.BUNDLE_OF[m]} "
                      f"(set --config.bundle or --config.bundles.<kind>)", stacklevel=2)
    names = [m for m in names if m not in missing]
    if not names:
        raise ValueError("no method left to evaluate")
    return names


def prepare_kwargs(config):
    d = config.data
    return dict(voxel=d.voxel, n_keypoints=d.n_keypoints, normal_k=d.normal_k)


def run_registration(config, workdir, progress=True):
    """Descriptor benchmark: returns ``(rows, markdown)``; writes results.{csv,md} and
    fmr_vs_tau2.png in ``workdir``."""
    bundles = bundle_paths(config)
    names = chosen_methods(config, method_lib.DESCRIPTORS, bundles)
    describers = {m: method_lib.descriptor(m, config.data.radius, bundles, config.fpfh_radius,
                                           config.chunk) for m in names}
    results = []
    for s in pair_sets(config):
        results += registration.evaluate_scene(
            s, describers, prepare_kwargs(config), config.tau1, config.tau2,
            config.ransac_distance, config.ransac_iterations, config.seed, progress)
    rows = [dict(method=r.method, scene=r.scene, ms_per_keypoint=r.ms_per_keypoint,
                 **r.summary) for r in results]
    os.makedirs(workdir, exist_ok=True)
    variant = " (rotated)" if config.rotate else ""
    md = report.write_tables(workdir, rows, report.REGISTRATION_COLUMNS,
                             report.REGISTRATION_TABLES, "results",
                             f"Registration benchmark{variant}")
    curve = registration.fmr_curve(results, config.tau2_curve, config.tau1)
    report.plot_fmr_curve(curve, config.tau2_curve, os.path.join(workdir, "fmr_vs_tau2.png"),
                          f"Feature-match recall vs τ2{variant}")
    return rows, md


def adapted_bundles(config, bundles, names, workdir, progress):
    """Test-time adaptation of the learned LRF bundles on the evaluation scans."""
    from sphere_jax import api, training
    out = dict(bundles)
    for kind in ("compass", "sound"):
        if kind in names:
            out[kind], _ = training.adapt(api.load_bundle(bundles[kind]), data_root(config),
                                          config.adapt_steps,
                                          os.path.join(workdir, f"adapted_{kind}"),
                                          progress=progress)
    return out


def run_lrf(config, workdir, progress=True):
    """LRF repeatability benchmark: returns ``(rows, markdown)``; writes lrf_results.{csv,md}
    and ``plots/<scene>_<i>_<j>_<method>.png`` in ``workdir``."""
    bundles = bundle_paths(config)
    names = chosen_methods(config, method_lib.LRFS, bundles)
    os.makedirs(workdir, exist_ok=True)
    if config.adapt_steps:
        bundles = adapted_bundles(config, bundles, names, workdir, progress)
    orienters = {m: method_lib.lrf(m, config.data.radius, bundles, config.chunk) for m in names}
    results, plot_dir = [], os.path.join(workdir, "plots")
    os.makedirs(plot_dir, exist_ok=True)
    for s in pair_sets(config):
        frags = scene_lib.prepare_all(s, config.seed, progress, **prepare_kwargs(config))
        scene_results = repeatability.evaluate_scene(
            s, orienters, match_dist=config.match_dist, rho=config.rho, seed=config.seed,
            progress=progress, fragments=frags)
        for r in scene_results:
            for row in r.pairs[:config.plot_pairs]:
                i, j = row["pair"]
                report.plot_repeatability(
                    frags[i].points, frags[i].points[row["keypoints"]], row["repeatable"],
                    os.path.join(plot_dir, f"{s.name}_{i}_{j}_{r.method}.png"),
                    f"{r.method}: {s.name} ({i}, {j}), Rep = {row['rep']:.3f}")
        results += scene_results
    rows = [dict(method=r.method, scene=r.scene, **r.summary) for r in results]
    variant = " (rotated)" if config.rotate else ""
    md = report.write_tables(workdir, rows, report.LRF_COLUMNS, report.LRF_TABLES,
                             "lrf_results", f"LRF repeatability{variant}")
    return rows, md


def run(config, workdir, progress=True):
    if config.task == "registration":
        return run_registration(config, workdir, progress)
    if config.task == "lrf":
        return run_lrf(config, workdir, progress)
    if config.task == "objects":
        from sphere_jax.eval import objects
        return objects.run(config, workdir, progress)
    if config.task == "recognition":
        from sphere_jax.eval import recognition
        return recognition.run(config, workdir, progress)
    if config.task == "pose":
        from sphere_jax.eval import pose
        return pose.run(config, workdir, progress)
    raise ValueError(f"config.task must be one of registration, lrf, objects, recognition, "
                     f"pose; got {config.task!r}")

