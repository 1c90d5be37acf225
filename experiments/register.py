"""Register two scans: ``python -m experiments.register SOURCE TARGET [--out DIR]``.

SOURCE and TARGET are point files (PLY, PCD, OFF, XYZ/TXT, NPY) in any unit. Prints the 4×4
``T`` with ``p_target = T · p_source``, the matches, RANSAC inliers, ICP fitness and RMSE and
the time of each stage; ``--out DIR`` also writes ``transform.txt``, ``source_registered.ply``
and ``before_after.png``. ``--voxel`` and ``--radius`` default to ``auto``: chosen from the
clouds so that a support holds as many points as at training time (:mod:`sphere_jax.align`),
and printed. A registration that does not succeed (too few points, no mutual matches, no
RANSAC consensus, ICP fitness below ``--min-fitness``) prints ``FAILED: <reason>`` and exits
with status 3; one that succeeds without confidence (fewer than
``pipeline.CONFIDENT_INLIERS`` RANSAC inliers, or fewer than ``pipeline.RIVAL_MARGIN`` times the
best other transform's) prints ``registered, unconfirmed`` and why (docs/usage.md).

    python -m experiments.register a.ply b.ply --method=fpfh --voxel=0.05 --out=runs/ab
    python -m experiments.register a.ply b.ply --method=lead@compass
    python -m experiments.register a.ply b.ply --method=lead@compass --adapt=5 --out=runs/ab
"""
from __future__ import annotations

import os
import sys

import numpy as np

from experiments import cli
from sphere_jax import align
from sphere_jax.features import registry
from sphere_jax.registration import pipeline


FAILED = 3          # exit status of a registration that did not succeed (2: bad usage)


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("source")
    parser.add_argument("target")
    parser.add_argument("--method", default=align.DEFAULT_METHOD,
                        choices=registry.spellings("descriptor", "voted"),
                        help="descriptor[@frame][+vote] or its key (lead@compass = "
                             "lead_compass)")
    parser.add_argument("--voxel", type=cli.scale, default="auto")
    parser.add_argument("--radius", type=cli.scale, default="auto")
    parser.add_argument("--keypoints", type=cli.positive_int, default=pipeline.DEFAULT_KEYPOINTS,
                        help="random keypoints per cloud (fewer: faster, lower recall); a "
                             "quarter are described first, then half, then all, until they "
                             "register with confidence")
    parser.add_argument("--no-progressive", action="store_true",
                        help="describe all the keypoints at once")
    parser.add_argument("--bundle", default=None,
                        help="a bundle replacing the shipped one of its kind; several, "
                             "comma-separated (e.g. an adapted Compass and LEAD)")
    parser.add_argument("--adapt", type=cli.positive_number, default=None, metavar="MINUTES",
                        help="adapt the method's networks to these two scans, without labels "
                             "(Compass and LEAD side by side for lead@compass; kept in "
                             "OUT/adapted with --out), register with them too and keep the "
                             "better result")
    parser.add_argument("--no-icp", action="store_true")
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--out", default=None, help="folder for the matrix, cloud and picture")
    parser.add_argument("--min-inliers", type=cli.non_negative_int, default=pipeline.MIN_INLIERS,
                        help="fewer RANSAC inliers is a failed registration")
    parser.add_argument("--min-fitness", type=cli.fraction, default=pipeline.MIN_FITNESS,
                        help="a lower ICP fitness is a failed registration")
    args = parser.parse_args(argv)
    from sphere_jax import workdirs
    from sphere_jax.data.readers import io
    with cli.refusals(arguments=True):
        clouds = io.read_points(args.source), io.read_points(args.target)
        source, target = (c.points for c in clouds)
        for path, cloud in zip((args.source, args.target), clouds):
            if cloud.dropped:
                print(f"{path}: {cloud.dropped} of {cloud.dropped + len(cloud)} points have "
                      f"non-finite coordinates; left out", file=sys.stderr)
        if args.bundle is not None:                # before the work: kinds and paths
            align.method_bundles(registry.resolve(args.method), args.bundle)
        if args.out:                               # before the work, not after it
            workdirs.prepare(args.out, "--out")
    with cli.refusals():
        result = align.register(source, target, args.method, args.voxel, args.radius,
                                args.keypoints, args.seed, args.bundle, not args.no_icp,
                                args.min_inliers, args.min_fitness, args.adapt,
                                os.path.join(args.out, "adapted") if args.out else None,
                                not args.no_progressive)
    print(result.summary())
    if not result.ok:                              # scripts over many pairs can tell
        sys.exit(FAILED)
    if args.out:
        write_outputs(args.out, source, target, result)
        print(f"written to {args.out}")


def write_outputs(out, source, target, result):
    """``transform.txt``, the moved source as PLY and a before/after picture."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from sphere_jax.data.readers import io
    os.makedirs(out, exist_ok=True)
    np.savetxt(os.path.join(out, "transform.txt"), result.transform, fmt="%.8f",
               header="p_target = T p_source")
    moved = source @ result.transform[:3, :3].T + result.transform[:3, 3]
    io.write_ply(os.path.join(out, "source_registered.ply"), moved)
    rng = np.random.default_rng(0)
    thin = lambda p: p[rng.choice(len(p), min(len(p), 20000), replace=False)]
    fig = plt.figure(figsize=(11, 5))
    for k, (title, pts) in enumerate((("before", source), ("after", moved))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.scatter(*thin(target).T, s=0.2, c="tab:blue", alpha=0.4, label="target")
        ax.scatter(*thin(pts).T, s=0.2, c="tab:orange", alpha=0.4, label="source")
        ax.set_axis_off()
        ax.set_title(f"{title} ({result.method}, fitness {result.fitness:.2f})"
                     if k else title)
    fig.savefig(os.path.join(out, "before_after.png"), dpi=110, bbox_inches="tight")
    plt.close(fig)


if __name__ == "__main__":
    main()
