"""Write the embedded default data, or pack training scans for another machine.

    python -m experiments.make_data --out=DIR [--seed=0]
    python -m experiments.make_data --pack=embedded,../shared/data/... --out=.pack [--voxel=0.02]
    python -m experiments.make_data --lidar=../shared/data/3dmatch/7-scenes-redkitchen --out=DIR

The first: synthetic indoor scenes in the 3DMatch layout, a ModelNet-layout shape set, RGB-D
object frames and object crops in the Washington RGB-D layout (see
:mod:`sphere_jax.data.generators.synthetic`); same seed, same bytes. The second: each entry of
a ``data.root`` list voxelised once (:func:`sphere_jax.data.pipeline.pack_scans`), one folder
per entry; ``--config.train.pack=DIR`` then trains a config on them, keeping its
``data.root``, with the same keypoints and batches and without open3d, the renderer or the
real scans (``experiments/gpu_train.sh`` carries one to a lent accelerator). The third:
a 3DMatch scene's fragments as a 32-beam spinning LiDAR at their first camera sees them
(:mod:`sphere_jax.data.generators.lidar`), a sensor the shipped bundles never saw; evaluate
them with the source's ground truth (``--config.data.gt=``, the folder above its
``<scene>-evaluation``).
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
    args = parser.parse_args(argv)
    t0 = time.time()
    if args.pack is not None and args.lidar is not None:
        parser.error("--pack and --lidar are two jobs: give one")
    # An option of another job would be ignored without a word.
    if args.voxel is not None and args.pack is None:
        parser.error("--voxel is the pack's voxel: give it with --pack")
    if args.scenes is not None and (args.pack is not None or args.lidar is not None):
        parser.error("--scenes is for the default data, not --pack or --lidar")
    if args.lidar is not None:
        from sphere_jax.data.generators import lidar
        if not args.out:
            parser.error("--lidar needs --out")
        with cli.refusals(arguments=True):
            counts = lidar.scan_fragments(args.lidar, args.out, seed=args.seed)
        print(json.dumps(counts, indent=1))
    elif args.pack is not None:
        from sphere_jax.data import pipeline
        if not args.out:
            parser.error("--pack needs --out")
        with cli.refusals(arguments=True):
            pipeline.scan_paths(args.pack)          # every entry exists, before any work
        with cli.refusals():
            folders = pipeline.pack_scans(args.pack, args.voxel or PACK_VOXEL, args.out)
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
