"""The training data of a config: its source of patches or shapes, and the batch of a step."""
from __future__ import annotations

import os

from sphere_jax import checks, models
from sphere_jax.training import warm_start
from sphere_jax.data import held_out, oriented, patch_source, scan_roots, shape_source
from sphere_jax.data.generators import synthetic


# Turned copies of each training shape a Compass + PointNet trained on turned shapes sees
# (``data.rotate``): each is oriented once, so the copies are the turns it can learn from.
ROTATED_COPIES = 8


def check_roots(config, spec=None):
    """What can be refused in ``config.data.root`` before any data is read or made: an entry
    that does not exist, one that names an evaluation scene
    (:class:`~sphere_jax.checks.ConfigError`). ``spec``: the model kind's, where the caller
    has it."""
    d = config.data
    if (spec or models.spec(config.model)).labelled or d.get("shapes", False):
        return
    entries = scan_roots.root_entries(d.root)
    allow = bool(d.get("allow_evaluation_scenes", False))
    pack = config.train.get("pack", "")
    if pack:                            # another machine: the entries are read from the pack,
        packed = [p for f in scan_roots.packed_folders(d.root, pack)      # which names where
                  for p in scan_roots.find_scans(f)]                      # each scan came from
        held_out.check_training_scans(
            entries + [scan_roots.scan_folder_label(p) for p in packed], allow)
        return
    held_out.check_training_scans([scan_roots.entry_path(e) for e in entries], allow)
    for entry in entries:
        if not entry.startswith("embedded") and not os.path.exists(scan_roots.entry_path(entry)):
            raise checks.ConfigError("config.data.root", "comma-separated scan files or "
                                     "folders, 'embedded:N' or 'shared/<path>'", entry)


def build_source(config, orient_shapes=None, progress=True, spec=None, roots_checked=False):
    """The data of ``config.data``: a :class:`~sphere_jax.data.patch_source.PatchSource` of the
    training scans (refused where they hold an evaluation scene, unless
    ``data.allow_evaluation_scenes``) or a :class:`~sphere_jax.data.shape_source.ShapeSource` —
    for a classifier with ``config.orient_bundle``, its shapes in the frames
    ``orient_shapes`` gives them (:func:`check_orient`), each oriented once
    (:mod:`sphere_jax.data.oriented`). ``spec``: the model kind's, where the caller has it;
    ``roots_checked``: :func:`check_roots` has passed already."""
    d = config.data
    if (spec or models.spec(config.model)).labelled or d.get("shapes", False):
        root = scan_roots.entry_path(d.root) if d.root else synthetic.default_root("modelnet")
        source = shape_source.ShapeSource(root, d.n_points, config.seed,
                                      d.get("holdout_every", shape_source.HOLDOUT_EVERY),
                                      d.get("val_every", shape_source.HOLDOUT_EVERY))
        if not config.get("orient_bundle"):
            return source
        check_orient(config, orient_shapes)
        copies = d.get("rotated_copies", ROTATED_COPIES) if d.get("rotate", False) else 0
        return oriented.oriented_source(source, orient_shapes, copies, config.seed, progress)
    allow = bool(d.get("allow_evaluation_scenes", False))
    if not roots_checked:            # the entries first (before an RGB-D sequence is fused),
        check_roots(config, spec)    # then every scan and its origin
    groups = scan_roots.scan_groups(d.root, config.train.get("pack", ""))
    scans = [p for g in groups for p in g]
    held_out.check_training_scans(
        scans + [scan_roots.scan_folder_label(p) for p in scans], allow)
    return patch_source.PatchSource([p for g in groups for p in g], d.voxel, d.keypoint_leaf,
                                d.radius, d.n_points, d.min_points, d.val_fraction, config.seed,
                                groups=[k for k, g in enumerate(groups) for _ in g],
                                weights=scan_roots.parse_weights(d.get("root_weights", ""),
                                                               len(groups)))


def check_orient(config, orient_shapes):
    """A classifier trained on oriented shapes (``config.orient_bundle``) needs the function
    that orients them; training runs no bundle itself, so the caller passes it
    (:func:`sphere_jax.bundles.inference.shape_orienter`)."""
    if config.get("orient_bundle") and orient_shapes is None:
        raise checks.ConfigError(
            "config.orient_bundle", "empty unless train_and_evaluate gets orient_shapes= "
            "(sphere_jax.bundles.inference.shape_orienter(config.orient_bundle); "
            "experiments.train passes it)", config.orient_bundle)


def get_batch(config, source, step, split="train", spec=None):
    """Batch ``step`` of ``split`` (a function of the seed and the step alone: resumed and
    continued runs draw what the uninterrupted run would have). A classifier with
    ``config.orient_bundle`` reads shapes :func:`build_source` oriented already (turned at
    random before, with ``data.rotate``). ``spec``: the model kind's, where the caller has
    it."""
    spec, bs = spec or models.spec(config.model), config.train.batch_size
    if not isinstance(source, shape_source.ShapeSource):
        added = warm_start.DATA_ADDED
        return source.batch(step, bs, split, copies=spec.copies, occlusion=config.data.occlusion,
                            copy_draw=config.data.get("copy_draw", added["copy_draw"]),
                            copy_jitter=config.data.get("copy_jitter", added["copy_jitter"]))
    if not spec.labelled:                                       # Compass on whole shapes
        return source.batch(step, bs, split, copies=spec.copies,
                            occlusion=config.data.occlusion)
    rotate = config.data.get("rotate", False) and not config.get("orient_bundle")
    return source.batch(step, bs, split, rotate=rotate)
