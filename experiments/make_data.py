"""Write the embedded default data: ``python -m experiments.make_data --out=DIR [--seed=0]``.

Synthetic indoor scenes in the 3DMatch layout, a ModelNet-layout shape set, RGB-D object
frames and object crops in the Washington RGB-D layout (see :mod:`sphere_jax.data.generators.synthetic`).
Same seed, same bytes.
"""
from __future__ import annotations

import argparse
import json
import time

from sphere_jax.data.generators import synthetic


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None,
                        help=f"output folder (default: {synthetic.default_data_dir()})")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenes", type=int, default=2)
    args = parser.parse_args(argv)
    out = args.out or synthetic.default_data_dir(args.seed)
    t0 = time.time()
    summary = synthetic.make_all(out, args.seed, n_scenes=args.scenes)
    summary["washington"] = synthetic.make_default_objects(out, args.seed)
    print(json.dumps(summary, indent=1))
    print(f"wrote {out} in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
