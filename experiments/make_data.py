"""Write the embedded default data, or pack training scans for another machine.

    python -m experiments.make_data --out=DIR [--seed=0]
    python -m experiments.make_data --pack=embedded,../shared/data/... --out=.pack [--voxel=0.02]
    python -m experiments.make_data --lidar=../shared/data/3dmatch/7-scenes-redkitchen --out=DIR
    python -m experiments.make_data --validation=../shared/data/training_scans/7-scenes-stairs \
        --out=DIR [--frames=25]

The first: synthetic indoor scenes in the 3DMatch layout, a ModelNet-layout shape set, RGB-D
object frames and object crops in the Washington RGB-D layout (see
:mod:`sphere_jax.data.generators.synthetic`); same seed, same bytes. The second: each entry of
a ``data.root`` list voxelised once (:func:`sphere_jax.data.scan_roots.pack_scans`), one folder
per entry; ``--config.train.pack=DIR`` then trains a config on them, keeping its
``data.root``, with the same keypoints and batches and without open3d, the renderer or the
real scans (``experiments/gpu_train.sh`` carries one to a lent accelerator). The third:
a 3DMatch scene's fragments as a 32-beam spinning LiDAR at their first camera sees them
(:mod:`sphere_jax.data.generators.lidar`), a sensor the shipped bundles never saw; evaluate
them with the source's ground truth (``--config.data.gt=``, the folder above its
``<scene>-evaluation``). The fourth: validation pairs of a training scene, fragments fused from
its posed RGB-D sequences (``--frames`` frames each) with a ``gt.log`` from their poses
(:mod:`sphere_jax.data.validation`): settings are chosen on them, never on evaluation scenes.
"""
from __future__ import annotations

import json
import time

from experiments import cli

PACK_VOXEL = 0.02              # m: the voxel of the 'mid' configs, which train on packs


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("--out", default=None,
                        help="output folder (default data: the package's cache folder)")
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--scenes", type=cli.positive_int, default=None,
                        help="synthetic scenes of the default data")
    parser.add_argument("--pack", default=None,
                        help="a data.root list to pack (voxelised scans) instead")
    parser.add_argument("--voxel", type=cli.positive_number, default=None,
                        help=f"the pack's voxel (m, default {PACK_VOXEL})")
    parser.add_argument("--lidar", default=None,
                        help="a 3DMatch scene folder to rescan with a spinning LiDAR instead")
    parser.add_argument("--validation", default=None,
                        help="posed RGB-D sequences of a training scene to fuse into "
                             "validation pairs instead")
    parser.add_argument("--frames", type=cli.positive_int, default=None,
                        help="frames per validation fragment (default 25)")
    args = parser.parse_args(argv)
    t0 = time.time()
    jobs = [f"--{j}" for j in ("pack", "lidar", "validation") if getattr(args, j) is not None]
    if len(jobs) > 1:
        parser.error(f"{' and '.join(jobs)} are {len(jobs)} jobs: give one")
    if args.frames is not None and args.validation is None:
        parser.error("--frames is the validation fragments' length: give it with --validation")
    # An option of another job would be ignored without a word.
    if args.voxel is not None and args.pack is None:
        parser.error("--voxel is the pack's voxel: give it with --pack")
    if args.scenes is not None and jobs:
        parser.error("--scenes is for the default data, not --pack, --lidar or --validation")
    if args.validation is not None:
        from sphere_jax.data import validation
        if not args.out:
            parser.error("--validation needs --out")
        n = args.frames or 25
        with cli.refusals(arguments=True):
            summary = validation.write_scene(args.validation, args.out, n, n)
        print(json.dumps({k: v for k, v in summary.items() if k != "fragments"}, indent=1))
    elif args.lidar is not None:
        from sphere_jax.data.generators import lidar
        if not args.out:
            parser.error("--lidar needs --out")
        with cli.refusals(arguments=True):
            counts = lidar.scan_fragments(args.lidar, args.out, seed=args.seed)
        print(json.dumps(counts, indent=1))
    elif args.pack is not None:
        from sphere_jax.data import scan_roots
        if not args.out:
            parser.error("--pack needs --out")
        with cli.refusals(arguments=True):
            scan_roots.scan_paths(args.pack)          # every entry exists, before any work
        with cli.refusals():
            folders = scan_roots.pack_scans(args.pack, args.voxel or PACK_VOXEL, args.out)
        print(json.dumps(folders, indent=1))
        print("data.root=" + ",".join(folders))
    else:
        from sphere_jax.data.generators import synthetic
        out = args.out or synthetic.default_data_dir(args.seed)
        scenes = {} if args.scenes is None else {"n_scenes": args.scenes}
        summary = synthetic.make_all(out, args.seed, **scenes)
        summary["washington"] = synthetic.make_default_objects(out, args.seed)
        print(json.dumps(summary, indent=1))
        args.out = out
    print(f"wrote {args.out} in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
