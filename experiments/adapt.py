"""Test-time adaptation (thesis 3.2.1): fine-tune a Compass or SOUND bundle, self-supervised,
on the scans it will be evaluated on.

    python -m experiments.adapt --bundle=compass --data=SCANS \\
        --steps=200 --workdir=runs/compass_adapted

The adapted bundle is written to ``WORKDIR/bundle``; re-running resumes like training.
"""
from __future__ import annotations

import argparse

from experiments import cli
from sphere_jax import api, training


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bundle", required=True)
    parser.add_argument("--data", required=True, help="folder of scans to adapt to")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--learning_rate", type=float, default=None)
    parser.add_argument("--workdir", required=True)
    args = parser.parse_args(argv)
    with cli.refusals():
        path, last = training.adapt(api.load_bundle(args.bundle), args.data, args.steps,
                                    args.workdir, args.learning_rate)
    print(f"adapted bundle in {path}: " + ", ".join(
        f"{k}={v:.4g}" for k, v in last.items() if isinstance(v, float)))


if __name__ == "__main__":
    main()
