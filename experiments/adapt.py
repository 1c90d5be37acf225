"""Adapt a bundle to your own scans, without labels: its own self-supervised loss (LEAD's and
LEAD-PN's reconstruction, Compass's and SOUND's frame consistency) on your scans, for a number
of minutes or steps, stopping early when the loss on held-back keypoints stops improving.

    python -m experiments.adapt --bundle=compass --data=SCANS --minutes=10 --workdir=runs/mine
    python -m experiments.adapt --bundle=compass,lead --data=SCANS --minutes=10 --workdir=runs/mine

``--data``: folders or scan files (PLY, PCD, XYZ, ...), comma-separated; no pose or ground
truth is read. The scale is chosen from the scans as ``experiments.register`` chooses it
(``--voxel``/``--radius`` to set it). The adapted bundle is written to ``WORKDIR/bundle``, its
model card naming the scans; ``register --method=lead@compass --bundle=WORKDIR/bundle`` uses
it, and re-running the same command resumes. Several bundles (comma-separated) adapt side by
side, each in its own process on its share of the cores, for the same minutes
(``sphere_jax/training/side_by_side.py``), into ``WORKDIR/<kind>/bundle``: both networks of
``lead@compass`` in the time of one (``register ... --bundle=W/compass/bundle,W/lead/bundle``).
A descriptor bundle keeps its whitening (``--refit_whitening``: fit one on your scans instead,
LEAD's ``compass`` one in the frames of ``--compass``, e.g. a Compass adapted before). What
adapting each kind measured: docs/training.md.
"""
from __future__ import annotations

import os

from experiments import cli
from sphere_jax import align, checks, workdirs
from sphere_jax.bundles import inference
from sphere_jax.data import scan_roots
from sphere_jax.data.readers import io
from sphere_jax.features import whitening_fit
from sphere_jax.training import adaptation, side_by_side
from sphere_jax.registration import scale

SCALE_SCANS = 8          # scans read to choose the scale (the first ones, in file order)


def auto_scale(roots, voxel="auto", radius="auto"):
    """``(voxel, radius)`` for ``roots``' scans: each given, or chosen from the scans as
    ``register`` chooses it (:func:`sphere_jax.registration.scale.auto_scale`)."""
    if "auto" in (voxel, radius):
        scans = scan_roots.scan_paths(roots)
        if not scans:
            raise checks.MissingError(f"--data={roots!r}: no scans found")
        clouds = [io.read_points(p).points for p in scans[:SCALE_SCANS]]
        auto_voxel, auto_radius = scale.auto_scale(*clouds)
        voxel = auto_voxel if voxel == "auto" else voxel
        radius = auto_radius if radius == "auto" else radius
    return (checks.positive(float(voxel), "voxel"), checks.positive(float(radius), "radius"))


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("--bundle", required=True,
                        help="a bundle folder or a shipped kind; several, comma-separated, "
                             "adapt side by side into WORKDIR/<kind>/bundle")
    parser.add_argument("--data", required=True, help="scan folders or files, comma-separated")
    parser.add_argument("--minutes", type=cli.positive_number, default=None,
                        help="wall-time budget (default 10 when --steps is not given)")
    parser.add_argument("--steps", type=cli.positive_int, default=None)
    parser.add_argument("--voxel", type=cli.scale, default="auto")
    parser.add_argument("--radius", type=cli.scale, default="auto")
    parser.add_argument("--patience", type=cli.non_negative_int, default=adaptation.PATIENCE,
                        help="evaluations without improvement before stopping, at least as "
                             "many as the best took (0: never stop early)")
    parser.add_argument("--learning_rate", type=cli.positive_number, default=None,
                        help="the rate after a short warm-up (default: a tenth of the "
                             "bundle's training rate)")
    parser.add_argument("--refit_whitening", action="store_true",
                        help="descriptor bundles: fit the whitening on these scans instead of "
                             "keeping the bundle's (on the bunny's scans it matched worse)")
    parser.add_argument("--compass", default=None,
                        help="with --refit_whitening, LEAD: the Compass bundle for the "
                             "'compass' whitening (default: the shipped one)")
    parser.add_argument("--workdir", required=True)
    args = parser.parse_args(argv)
    minutes = 10.0 if args.minutes is None and args.steps is None else args.minutes
    with cli.refusals(arguments=True):
        for name in ("minutes", "steps", "learning_rate"):
            checks.positive(getattr(args, name), name, integer=name == "steps")
        checks.non_negative(args.patience, "patience", integer=True)
        given = align.split_bundles(args.bundle)
        if not given:
            raise checks.InputError("bundle", "a bundle folder or kind, or several "
                                    "comma-separated", repr(args.bundle))
        bundles = [inference.load_bundle(b) for b in given]
        kinds = align.one_per_kind([b.kind for b in bundles])
        if args.compass is not None:                # before reading any scan
            whitening_fit.frame_bundle(args.compass)
        voxel, radius = auto_scale(args.data, args.voxel, args.radius)
        data = [adaptation.data_at_scale(b.config, voxel, radius) for b in bundles]
        workdirs.prepare(args.workdir, "--workdir")
    budget = (f", {minutes:g} min" if minutes else "") + (
        f", at most {args.steps} steps" if args.steps else "")
    with cli.refusals():
        several = len(bundles) > 1
        shares = side_by_side.core_shares(len(bundles))
        cores = "; cores " + ", ".join(f"{k} {list(c)}" for k, c in zip(kinds, shares))
        print(f"adapting {', '.join(kinds)}{' side by side' if several else ''} on "
              f"{args.data}: voxel {voxel:.4g}, radius {radius:.4g}{budget}"
              f"{cores if several else ''}")
        jobs = [(k, inference.bundle_path(b), os.path.join(args.workdir, k) if several
                 else args.workdir, d) for k, b, d in zip(kinds, given, data)]
        paths = side_by_side.adapt_side_by_side(jobs, args.data, args.steps, minutes,
                                                args.learning_rate, args.patience,
                                                shares=shares)
        for source, path in zip(given, paths):
            if args.refit_whitening:
                whitening_fit.fit_if_descriptor(path, args.compass,
                                                command=cli.command("experiments.adapt"))
            else:
                whitening_fit.keep_from(source, path)
    # What the bundle holds, not the last step's metrics: early stopping keeps the best weights.
    for path in paths:
        print(f"adapted bundle in {path}: {adaptation.outcome(path)}")


if __name__ == "__main__":
    main()
