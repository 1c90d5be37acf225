"""Adapt a bundle to your own scans, without labels: its own self-supervised loss (LEAD's and
LEAD-PN's reconstruction, Compass's and SOUND's frame consistency) on your scans, for a number
of minutes or steps, stopping early when the loss on held-back keypoints stops improving.

    python -m experiments.adapt --bundle=compass --data=SCANS --minutes=10 --workdir=runs/mine

``--data``: folders or scan files (PLY, PCD, XYZ, ...), comma-separated; no pose or ground
truth is read. The scale is chosen from the scans as ``experiments.register`` chooses it
(``--voxel``/``--radius`` to set it). The adapted bundle is written to ``WORKDIR/bundle``, its
model card naming the scans; ``register --method=lead@compass --bundle=WORKDIR/bundle`` uses
it, and re-running the same command resumes. A descriptor bundle keeps its whitening
(``--refit_whitening``: fit one on your scans instead, LEAD's ``compass`` one in the frames of
``--compass``, e.g. a Compass adapted before). What adapting each kind measured:
docs/training.md.
"""
from __future__ import annotations

from experiments import cli
from sphere_jax import align, api, checks, training, workdirs
from sphere_jax.data import pipeline
from sphere_jax.data.readers import io
from sphere_jax.features import whitening_fit
from sphere_jax.training import adaptation

SCALE_SCANS = 8          # scans read to choose the scale (the first ones, in file order)


def auto_data(bundle, roots, voxel="auto", radius="auto"):
    """``config.data`` overrides putting ``roots``' scans at the scale ``bundle`` was trained
    at (:func:`sphere_jax.align.auto_scale`), keypoints as dense relative to the support."""
    if "auto" in (voxel, radius):
        scans = pipeline.scan_paths(roots)
        if not scans:
            raise checks.MissingError(f"--data={roots!r}: no scans found")
        clouds = [io.read_points(p).points for p in scans[:SCALE_SCANS]]
        auto_voxel, auto_radius = align.auto_scale(*clouds)
        voxel = auto_voxel if voxel == "auto" else voxel
        radius = auto_radius if radius == "auto" else radius
    voxel, radius = checks.positive(float(voxel), "voxel"), checks.positive(float(radius),
                                                                             "radius")
    return adaptation.data_at_scale(bundle, voxel, radius)


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("--bundle", required=True, help="a bundle folder or a shipped kind")
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
        bundle = api.load_bundle(args.bundle)
        if args.compass is not None:                # before reading any scan
            whitening_fit.frame_bundle(args.compass)
        data = auto_data(bundle, args.data, args.voxel, args.radius)
        workdirs.prepare(args.workdir, "--workdir")
    with cli.refusals():
        print(f"adapting {bundle.kind} on {args.data}: voxel {data['voxel']:.4g}, radius "
              f"{data['radius']:.4g}" + (f", {minutes:g} min" if minutes else "")
              + (f", at most {args.steps} steps" if args.steps else ""))
        path = training.adapt(bundle, args.data, args.steps, args.workdir,
                              args.learning_rate, data=data, minutes=minutes,
                              patience=args.patience)
        if args.refit_whitening:
            whitening_fit.fit_if_descriptor(path, args.compass,
                                            command=cli.command("experiments.adapt"))
        else:
            whitening_fit.keep_from(args.bundle, path)
    # What the bundle holds, not the last step's metrics: early stopping keeps the best weights.
    print(f"adapted bundle in {path}: {adaptation.outcome(path)}")


if __name__ == "__main__":
    main()
