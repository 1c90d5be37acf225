"""Fit a descriptor bundle's whitening on its own training scans:
``python -m experiments.whiten --bundle=BUNDLE``.

Describes random keypoints of the scans the bundle trained on (``config.data.root``) and
stores, in the bundle, the linear map that gives every principal direction of those
descriptors unit variance (``whitening.npz``, ``whitening.json``;
:mod:`sphere_jax.bundles.whitening`): one for the kind's own frames and, for LEAD, one for
Compass frames (``--compass``, default the shipped Compass). ``describe`` then whitens by
default; what it buys on the redkitchen pairs: docs/results.md.

    python -m experiments.whiten --bundle=sphere_jax/weights/lead_mid/bundle
"""
from __future__ import annotations

from experiments import cli
from sphere_jax import checks
from sphere_jax.features import whitening_fit


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("--bundle", required=True, help="a descriptor bundle folder")
    parser.add_argument("--compass", default=None,
                        help="LEAD only: the Compass bundle whose frames the 'compass' "
                             "whitening is fitted in (default: the shipped one)")
    parser.add_argument("--scans", type=cli.positive_int, default=whitening_fit.SCANS)
    parser.add_argument("--keypoints", type=cli.positive_int, default=whitening_fit.KEYPOINTS,
                        help="random keypoints per scan")
    args = parser.parse_args(argv)
    with cli.refusals(arguments=True):
        checks.positive(args.scans, "scans", integer=True)
        checks.positive(args.keypoints, "keypoints", integer=True)
        whitening_fit.descriptor_bundle(args.bundle)
        if args.compass is not None:
            whitening_fit.frame_bundle(args.compass)
    with cli.refusals():
        whitening_fit.fit_bundle(args.bundle, args.compass, args.scans, args.keypoints,
                                 command=cli.command("experiments.whiten"))


if __name__ == "__main__":
    main()
