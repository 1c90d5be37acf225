"""Count the wrong results ``register`` calls ``registered``, per method, on scans with ground
truth; and fit the thresholds of that word on validation pairs.

    python -m experiments.registered --data=runs/validation --methods=lead_pn,fpfh \\
        --workdir=runs/registered_val --fit
    python -m experiments.registered --data=../shared/data/3dmatch/7-scenes-redkitchen \\
        --methods=lead_pn,lead@compass,fpfh --workdir=runs/registered_redkitchen

``--data``: folders of 3DMatch scenes or Stanford ``.conf`` sets (comma-separated); ``--gt``:
ground truth kept apart (3DLoMatch, LiDAR rescans). Each pair is registered by
``sphere_jax.register`` as a user calls it; rows go to ``WORKDIR/registered.csv`` (a rerun goes
on), its commands and thresholds to ``run.json``, the table of right / wrong results by
status to ``registered.md`` (``experiments.publish --registered=WORKDIR`` publishes it in
docs/registered.md). ``--fit`` also chooses
the thresholds (no wrong result ``registered``, the most right ones kept) — on validation
pairs only: settings are never chosen on evaluation scenes.
"""
from __future__ import annotations

import datetime
import json
import os

from experiments import cli
from sphere_jax import align, files, workdirs
from sphere_jax.registration import pipeline
from sphere_jax.eval import pair_sets
from sphere_jax.eval import registered as lib
from sphere_jax.features import registry


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("--data", required=True, help="comma-separated scan-set folders")
    parser.add_argument("--gt", default=None, help="ground truth folder, when kept apart")
    parser.add_argument("--methods", default=align.DEFAULT_METHOD,
                        help="comma-separated methods register takes")
    parser.add_argument("--workdir", required=True)
    parser.add_argument("--fit", action="store_true", help="fit the status's thresholds")
    args = parser.parse_args(argv)
    methods = [registry.resolve(m.strip(), ("descriptor", "voted")).key
               for m in args.methods.split(",") if m.strip()]
    with cli.refusals(arguments=True):
        workdir = workdirs.prepare(args.workdir)
        sets = [s for root in args.data.split(",") if root.strip()
                for s in pair_sets.find_pair_sets(root.strip(), gt_root=args.gt)]
    with cli.refusals():
        rows = lib.run(sets, methods, os.path.join(workdir, "registered.csv"))
    rows = [r for r in rows if r["method"] in methods]
    # A rerun in the same workdir (other data, more methods) adds its rows: the record keeps
    # every command that wrote them.
    path = os.path.join(workdir, lib.RECORD)
    before = {"commands": [], "methods": [], "data": []}
    if os.path.isfile(path):
        with open(path) as f:
            before = json.load(f)
    command = cli.command("experiments.registered")
    data = args.data + (f" (ground truth {args.gt})" if args.gt else "")
    record = {"task": "registered", "date": datetime.date.today().isoformat(),
              "commands": [c for c in before["commands"] if c != command] + [command],
              "data": [d for d in before["data"] if d != data] + [data],
              "methods": list(dict.fromkeys(before["methods"] + methods)),
              "thresholds": {"min_inliers": pipeline.CONFIDENT_INLIERS,
                             "margin": pipeline.RIVAL_MARGIN}}
    files.atomic_write(path, json.dumps(record, indent=1).encode())
    if args.fit:
        n, m, kept = lib.fit(rows)
        files.atomic_write(os.path.join(workdir, lib.FIT), json.dumps(
            {"min_inliers": n, "margin": m, "right_kept": kept}, indent=1).encode())
    text = lib.summary(workdir)
    files.atomic_write(os.path.join(workdir, "registered.md"), text.encode())
    print(text)


if __name__ == "__main__":
    main()
