"""The evaluation scenes, and the rule that training never sees them.

Every figure this project publishes is measured on these scenes; a model trained on any scan of
them would be scored on its own training geometry. Each scene lists the sources known to hold
it, as portable labels (:func:`sphere_jax.paths.portable`: ``shared/<rel>`` under the real
scans, ``embedded/<rel>`` under the synthetic data cache) — a folder covers every scan under
it, a file itself — and folder or file names that identify it wherever a copy lives (a user's
own download of 3DMatch, say). The embedded default rooms (seed 0) are the main job's
evaluation scenes; training draws its synthetic rooms from other seeds (``embedded:N``).

:func:`check_training_scans` is what training calls on its scan files: any match is refused
unless the run says it is an evaluation-scene experiment (``data.allow_evaluation_scenes``),
and then the bundle's training statement names the scenes (:func:`scenes_of`).
"""
from __future__ import annotations

import os
from typing import NamedTuple

from sphere_jax import checks, paths
from sphere_jax.data.generators import synthetic


class Scene(NamedTuple):
    name: str
    why: str                      # what the scene is evaluated for
    sources: tuple[str, ...]      # portable labels of folders or files
    names: tuple[str, ...]        # path components that identify it anywhere


EVALUATION_SCENES = (
    Scene("redkitchen", "3DMatch / 3DLoMatch registration and LRF repeatability",
          ("shared/3dmatch/7-scenes-redkitchen", "shared/3dmatch/demo_fullres",
           "shared/rgbd/3dmatch_toolbox"),
          # demo_fullres holds redkitchen fragments 0 and 1; the toolbox's RGB-D frames are
          # redkitchen seq-01 frames 8-57, from which fragment 0 was fused.
          ("7-scenes-redkitchen", "redkitchen", "demo_fullres", "3dmatch_toolbox")),
    Scene("bunny", "LRF repeatability and registration at object scale",
          ("shared/stanford/bunny",), ("bunny",)),
    Scene("sun3d-home_at", "a 3DMatch test scene: open3d's single scans are two of its views",
          # frag_115 registers onto home_at fragment 41 (79 % within 2 cm) and fragment.pcd
          # overlaps frag_115 by 82 %.
          ("shared/open3d_testdata/ColoredICP/frag_115.ply", "shared/open3d_testdata/fragment.pcd"),
          ("sun3d-home_at", "home_at")),
    # 3DMatch-named fragments whose scene no source documents: one of the test scenes, for
    # all anyone can tell, so they are held out like one.
    Scene("open3d Feature fragments", "none: 3DMatch fragments of no documented scene",
          ("shared/open3d_testdata/Feature",), ()),
    Scene("embedded rooms", "the main job's registration benchmark (eval_registration:quick)",
          (f"embedded/{os.path.basename(synthetic.default_data_dir(0))}/3dmatch",), ()),
)


class EvaluationSceneError(checks.ConfigError):
    """Training data that holds an evaluation scene."""


def scene_of(path) -> Scene | None:
    """The evaluation scene a scan file, folder or label (``shared/<rel>``, as bundles state
    their folders) belongs to, or None."""
    text = str(path).replace(os.sep, "/")
    label = text if text.startswith(("shared/", "embedded/")) else \
        paths.portable(text).replace(os.sep, "/")
    parts = [p.lower() for p in text.split("/")]
    for scene in EVALUATION_SCENES:
        if any(label == s or label.startswith(s + "/") or label.startswith(s + " ")
               for s in scene.sources):
            return scene
        if any(n in parts or any(p.startswith(n + "-") or p.startswith(n + ".")
                                 for p in parts) for n in scene.names):
            return scene
    return None


def scenes_of(paths_or_labels) -> list[str]:
    """Names of the evaluation scenes among ``paths_or_labels`` (sorted, each once)."""
    return sorted({s.name for p in paths_or_labels if (s := scene_of(p)) is not None})


def check_training_scans(scan_labels, allow=False) -> list[str]:
    """Refuse training scans of an evaluation scene; ``scan_labels``: each scan's path and
    the label of where it came from (a fused RGB-D sequence's folder, a pack's origin).
    Returns the scenes found (empty unless ``allow``)."""
    found = {}
    for label in scan_labels:
        scene = scene_of(label)
        if scene is not None:
            found.setdefault(scene.name, str(label))
    if found and not allow:
        listed = "; ".join(f"{name} ({example})" for name, example in sorted(found.items()))
        raise EvaluationSceneError(
            f"data.root holds scans of evaluation scenes: {listed}. Training and evaluation "
            f"never share a scene; drop those entries, or set "
            f"data.allow_evaluation_scenes=True for an evaluation-scene experiment (its bundle "
            f"then records the scenes)")
    return sorted(found)
