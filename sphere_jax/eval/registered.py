"""How often ``register``'s word is right: every pair with ground truth registered by
:func:`sphere_jax.align.register` exactly as a user calls it (automatic scale, progressive
keypoints, shipped bundles), each result sorted by status — ``registered`` (confident),
``unconfirmed`` or ``failed`` — and by truth: right when RRE < 15° and RTE is below the
registration's support radius (:func:`sphere_jax.eval.registration.registered`).

:func:`fit` chooses the two thresholds of the status (RANSAC inliers and their margin over the
best other transform, :data:`sphere_jax.registration.pipeline.CONFIDENT_INLIERS` and
:data:`~sphere_jax.registration.pipeline.RIVAL_MARGIN`) on rows of validation pairs; the
evaluation pairs only report the chosen ones.
"""
from __future__ import annotations

import csv
import json
import os

import numpy as np
from tqdm.auto import tqdm

from sphere_jax import align
from sphere_jax.registration import pipeline
from sphere_jax.eval.registration import registered, rre_rte

FIELDS = ("set", "i", "j", "method", "status", "right", "inliers", "rival", "matches",
          "fitness", "rre_deg", "rte", "radius", "seconds")
STATUSES = ("registered", "unconfirmed", "failed")


def status(reg: pipeline.Registration) -> str:
    return "failed" if not reg.ok else "registered" if reg.confident else "unconfirmed"


def status_at(row, min_inliers, margin) -> str:
    """The status a row's registration would have with these thresholds."""
    if row["status"] == "failed":
        return "failed"
    inliers, rival = int(row["inliers"]), int(row["rival"])
    return "registered" if inliers >= min_inliers and inliers >= margin * rival \
        else "unconfirmed"


def pair_row(pair_set, i, j, method, bundle=None):
    """Register scan j onto scan i (``p_i = T p_j``) and say how it went."""
    reg = align.register(pair_set.load(j), pair_set.load(i), method=method, bundle=bundle)
    rre, rte = rre_rte(reg.transform, pair_set.transforms[(i, j)])
    return {"set": pair_set.name, "i": i, "j": j, "method": method, "status": status(reg),
            "right": int(registered(rre, rte, reg.radius)), "inliers": reg.inliers,
            "rival": reg.rival, "matches": reg.matches, "fitness": round(reg.fitness, 4),
            "rre_deg": round(rre, 3), "rte": float(f"{rte:.4g}"),
            "radius": float(f"{reg.radius:.4g}"), "seconds": round(sum(reg.seconds.values()), 2)}


def read_rows(path) -> list[dict]:
    if not os.path.isfile(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def run(pair_sets, methods, out_csv, bundle=None, progress=True) -> list[dict]:
    """Rows of every pair of ``pair_sets`` by every method, appended to ``out_csv`` one by one
    (a rerun goes on where the last stopped)."""
    rows = read_rows(out_csv)
    done = {(r["set"], str(r["i"]), str(r["j"]), r["method"]) for r in rows}
    todo = [(s, i, j, m) for m in methods for s in pair_sets for (i, j) in s.pairs
            if (s.name, str(i), str(j), m) not in done]
    new_file = not os.path.isfile(out_csv)
    with open(out_csv, "a", newline="") as f:
        writer = csv.DictWriter(f, FIELDS)
        if new_file:
            writer.writeheader()
        for s, i, j, m in tqdm(todo, desc="register", unit="pair", disable=not progress):
            row = pair_row(s, i, j, m, bundle)
            writer.writerow(row)
            f.flush()
            rows.append({k: str(v) for k, v in row.items()})
    return rows


def counts(rows, min_inliers=None, margin=None) -> dict:
    """``{method: {(right, status): n}}``; with thresholds, the statuses they would give."""
    out = {}
    for r in rows:
        st = r["status"] if min_inliers is None else status_at(r, min_inliers, margin)
        key = ("right" if int(r["right"]) else "wrong", st)
        by = out.setdefault(r["method"], {})
        by[key] = by.get(key, 0) + 1
    return out


def table(rows, min_inliers=None, margin=None) -> str:
    """Markdown: per method, pairs and right / wrong results by status."""
    head = ["method", "pairs"] + [f"{t} {s}" for t in ("right", "wrong") for s in STATUSES]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for method, by in counts(rows, min_inliers, margin).items():
        cells = [by.get((t, s), 0) for t in ("right", "wrong") for s in STATUSES]
        out.append(f"| {method} | {sum(cells)} | " + " | ".join(map(str, cells)) + " |")
    return "\n".join(out)


def fit(rows, inlier_grid=tuple(range(10, 81, 5)),
        margin_grid=tuple(np.round(np.arange(1.0, 4.01, 0.25), 2))):
    """``(min_inliers, margin, kept)``: of the thresholds under which no wrong result of
    ``rows`` is ``registered``, those keeping the most right results ``registered`` (ties: the
    lowest thresholds); ``kept`` is that share of the right results that succeeded."""
    succeeded = [r for r in rows if r["status"] != "failed"]
    right = [r for r in succeeded if int(r["right"])]
    wrong = [r for r in succeeded if not int(r["right"])]
    best = None
    for n in inlier_grid:
        for m in margin_grid:
            if any(status_at(r, n, m) == "registered" for r in wrong):
                continue
            kept = np.mean([status_at(r, n, m) == "registered" for r in right]) if right else 0
            if best is None or kept > best[2] + 1e-12:
                best = (int(n), float(m), float(kept))
    return best


RECORD = "run.json"        # commands, data, methods, thresholds: what the summary says
# docs/registered.md above its generated sections (experiments.publish --registered).
PAGE = """# register's status against the truth

Generated by `python -m experiments.publish --registered=WORKDIR` from the records of
`python -m experiments.registered` runs (docs/records); do not edit.

Every pair with ground truth is registered by `sphere_jax.register` as a user calls it
(automatic scale, progressive keypoints, shipped bundles), each result counted by status —
`registered`, `unconfirmed` or `failed` — and by truth: right when RRE < 15° and RTE is below
the support radius `register` chose. The thresholds of `registered`
(`registration.pipeline.CONFIDENT_INLIERS`, `RIVAL_MARGIN`) were chosen on the validation pairs
alone, by `--fit`; the evaluation sections report them. Paths: `runs/validation` is `make_data
--validation` of `training_scans/7-scenes-stairs` and of `shelf-bin-realsense` (`--frames=10`),
`runs/lidar_data` is `make_data --lidar` of redkitchen (docs/data.md), the rooms of seed 5 are
`sphere_jax.data.generators.synthetic.ensure_training_rooms(5)` (no shipped bundle trained on
them).

On the validation pairs the held-out rooms' wrong results are exact symmetries of their rooms
(90° or 180° off) with many inliers, which geometry cannot tell apart and which push both
thresholds up. At object scale (the bunny) a flipped pose can hold all the consensus with no
other transform rivalling it: the tables show where such a result is still called
`registered`, and how many of the right results each set keeps `registered`.
"""
FIT = "fit.json"


def summary(folder) -> str:
    """The run's markdown from its files (its workdir or its record in docs/records): its
    commands, the right and wrong results of each method by status under the thresholds it
    ran with and, for a run that fitted them (``fit.json``), under the fitted ones."""
    with open(os.path.join(str(folder), RECORD)) as f:
        record = json.load(f)
    rows = [r for r in read_rows(os.path.join(str(folder), "registered.csv"))
            if r["method"] in record["methods"]]
    n, m = record["thresholds"]["min_inliers"], record["thresholds"]["margin"]
    out = ["# register's status against the truth", ""]
    out += ["\n\nthen\n\n".join(f"`{c}`" for c in record["commands"])]
    out += ["", f"Thresholds: {n} RANSAC inliers, {m:g}× the best other transform's.", "",
            table(rows, n, m)]
    path = os.path.join(str(folder), FIT)
    if os.path.isfile(path):
        with open(path) as f:
            fitted = json.load(f)
        out += ["", f"Fitted here: {fitted['min_inliers']} inliers, {fitted['margin']:g}× the "
                f"rival's; {fitted['right_kept']:.1%} of the right results that succeeded stay "
                f"registered.", "", table(rows, fitted["min_inliers"], fitted["margin"])]
    return "\n".join(out) + "\n"
