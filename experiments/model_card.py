"""Render a bundle's model card again from its files (``sphere_jax.bundles.model_card``).

    python -m experiments.model_card BUNDLE [--metrics=W/metrics.jsonl] [--command="..."]
    python -m experiments.model_card --index       # sphere_jax/weights/README.md

``--metrics`` copies a training log into the bundle first and ``--command`` records the command
that trained it (for a bundle written before cards existed).
"""
from __future__ import annotations


from experiments import cli


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("bundle", nargs="?",
                        help="a bundle folder (the 'bundle' a training run writes)")
    parser.add_argument("--index", action="store_true",
                        help="write the shipped bundles' index instead")
    parser.add_argument("--metrics", default=None, help="the run's metrics.jsonl to copy in")
    parser.add_argument("--command", default=None, help="the command that trained it")
    args = parser.parse_args(argv)
    from sphere_jax import paths
    from sphere_jax.bundles import model_card
    from sphere_jax.models import shipped
    if args.index == bool(args.bundle):
        parser.error("give a bundle folder or --index")
    with cli.refusals(arguments=True):          # it reads only the bundle it is given
        if args.index:
            print(model_card.weights_index(paths.weights_root(), shipped.SHIPPED))
        else:
            print(model_card.write(args.bundle, args.metrics, args.command))


if __name__ == "__main__":
    main()
