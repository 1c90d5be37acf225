"""Test-time adaptation (thesis 3.2.1): fine-tune a Compass or SOUND bundle, self-supervised,
on the scans it will be evaluated on.

    python -m experiments.adapt --bundle=checkpoints/compass_cpu/bundle --data=SCANS \\
        --steps=200 --workdir=runs/compass_adapted

The adapted bundle is written to ``WORKDIR/bundle``; re-running resumes like training.
"""
from __future__ import annotations

import argparse

from sphere_jax import api, training


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bundle", required=True)
    parser.add_argument("--data", required=True, help="folder of scans to adapt to")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--learning_rate", type=float, default=None)
    parser.add_argument("--workdir", required=True)
    args = parser.parse_args(argv)
    bundle = api.load_bundle(args.bundle)
    if bundle.kind not in ("compass", "sound"):
        raise SystemExit(f"test-time adaptation is for compass and sound bundles, not "
                         f"{bundle.kind!r}")
    config = bundle.config
    with config.unlocked():
        config.data.root = args.data
        config.train.steps = args.steps
        config.train.checkpoint_every = max(1, min(config.train.checkpoint_every, args.steps))
        config.train.eval_every = max(1, min(config.train.eval_every, args.steps))
        config.train.log_every = max(1, min(config.train.log_every, args.steps))
        if args.learning_rate:
            config.train.learning_rate = args.learning_rate
    _, last = training.train_and_evaluate(config, args.workdir, init_variables=bundle.variables)
    print(f"adapted bundle in {args.workdir}/bundle: " + ", ".join(
        f"{k}={v:.4g}" for k, v in last.items() if isinstance(v, float)))


if __name__ == "__main__":
    main()
