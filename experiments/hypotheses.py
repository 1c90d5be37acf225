"""Frame hypotheses: how often one of Compass's strongest modes is the right frame, and what
LEAD's matching gains when it matches over them (:mod:`sphere_jax.eval.hypotheses`).

    python -m experiments.hypotheses --data=runs/validation --workdir=runs/hyp_val
    python -m experiments.hypotheses --data=../shared/data/3dmatch/7-scenes-redkitchen \\
        --compass=runs/c67_real12k/bundle --workdir=runs/hyp_redkitchen

``--data``: folders of 3DMatch scenes (comma-separated); ``--compass`` / ``--lead``: bundles
(default: the shipped ones; LEAD's ``compass`` whitening whitens every hypothesis). Writes
``WORKDIR/hypotheses.csv`` (one row per pair and number of hypotheses) and
``hypotheses.md`` (means over pairs per scene set). Choose on validation pairs; evaluation
scenes only report.
"""
from __future__ import annotations

import dataclasses
import os

from experiments import cli
from sphere_jax import checks, files, workdirs
from sphere_jax.bundles import inference
from sphere_jax.eval import hypotheses, report

COLUMNS = ["scene", "pair", "h", "frame_recall", "inlier_ratio", "correct", "matches"]


def table(rows, command) -> str:
    out = [f"# Frame hypotheses\n\n`{command}`\n",
           "| scene set | h | pairs | frame recall | inlier ratio | correct | matches |",
           "|---|---|---|---|---|---|---|"]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        for h in sorted({r["h"] for r in rows}):
            sel = [r for r in rows if r["scene"] == scene and r["h"] == h]
            mean = lambda k, s=sel: sum(float(r[k]) for r in s) / len(s)
            out.append(f"| {scene} | {h} | {len(sel)} | {mean('frame_recall'):.3f} | "
                       f"{mean('inlier_ratio'):.3f} | {mean('correct'):.0f} | "
                       f"{mean('matches'):.0f} |")
    return "\n".join(out) + "\n"


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("--data", required=True, help="comma-separated scene-set folders")
    parser.add_argument("--compass", default="compass", help="Compass bundle (folder or kind)")
    parser.add_argument("--lead", default="lead", help="LEAD bundle (folder or kind)")
    parser.add_argument("--hs", default="1,2,3,4", help="numbers of hypotheses to score")
    parser.add_argument("--keypoints", type=int, default=2500, help="random keypoints a scan")
    parser.add_argument("--workdir", required=True)
    args = parser.parse_args(argv)
    with cli.refusals(arguments=True):
        hs = tuple(int(h) for h in args.hs.split(",") if h.strip().isdigit())
        if len(hs) != len(args.hs.split(",")) or min(hs) < 1:
            raise checks.InputError("--hs", "comma-separated numbers >= 1", repr(args.hs))
        workdir = workdirs.prepare(args.workdir)
        compass, lead = (inference.bundle_path(b) for b in (args.compass, args.lead))
        for path in (compass, lead):
            inference.cached_bundle(path)                   # a bad bundle, before any work
    rows = []
    with cli.refusals():
        for root in (r.strip() for r in args.data.split(",") if r.strip()):
            rows += [dataclasses.asdict(r) for r in hypotheses.run(
                root, compass, lead, hs, n_keypoints=args.keypoints)]
    for r in rows:
        r["pair"] = "-".join(map(str, r["pair"]))
    command = cli.command("experiments.hypotheses")
    files.atomic_write(os.path.join(workdir, "hypotheses.csv"),
                       report.to_csv(rows, COLUMNS).encode())
    text = table(rows, command)
    files.atomic_write(os.path.join(workdir, "hypotheses.md"), text.encode())
    print(text)


if __name__ == "__main__":
    main()
