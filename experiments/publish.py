"""Publish evaluation runs: ``docs/results.md``, the README's headline table and the model cards
are generated from the runs' own files, so a rerun updates them.

    python -m experiments.publish RUN_DIR [RUN_DIR ...] [--headline=RUN_DIR]
        [--adaptation=BEFORE_RUN:AFTER_RUN ...] [--targets=MATCH,LOMATCH,ROTATED,LRF,LRF_BUNNY]
        [--classification=RUN_DIR] [--drop=SECTION_KEY ...] [--fresh]

Each RUN_DIR is an ``experiments.evaluate`` workdir (its ``run.json`` says the command, the
bundles and the date; its markdown and CSV hold the tables, a registration run's pair votes in
``votes.md``). ``docs/results.md`` has one section per run, keyed by its folder: a run published
again replaces its own section, the others stay but those ``--drop`` names (``--fresh``: only
the runs given, in their order). ``--headline`` (a registration run) replaces the table between
the README's ``headline`` markers; every bundle a run used gets the run's table in its model
card (:func:`sphere_jax.bundles.model_card.add_evaluation`). ``--adaptation`` pairs a run with the
shipped bundles and the same run with adapted ones (``experiments.adapt``, or an LRF run's own
``adapt_steps``): a section compares them method by method and says what each bundle adapted on,
for how long. ``--targets`` fills the README's ``targets`` block: the accuracy targets, measured
and met or not (:mod:`experiments.standing`); ``--classification`` its
``classification-targets`` block from an ``eval_classification`` run.
"""
from __future__ import annotations

import glob
import json
import os
import re

from experiments import cli
from sphere_jax.data.readers import io
from sphere_jax.eval import repeatability, report

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(REPO, "docs", "results.md")
README = os.path.join(REPO, "README.md")
HEADLINE = (("fmr", "FMR", "{:.2f}"), ("inlier_ratio", "inlier ratio", "{:.3f}"),
            ("n_correct", "correct / pair", "{:.0f}"), ("rr", "RR", "{:.2f}"),
            ("ms_per_keypoint", "ms / keypoint", "{:.2f}"))
# A description time measured while other processes used more than this share of the cores
# is marked as shared (sphere_jax/eval/timing.py).
SHARED = 0.1
# Tables a task writes beside its main one that its section shows too: the pair vote's rotation
# errors say how far a voted method's frames are from the truth, pair by pair.
BESIDE = {"registration": ("votes",)}


def stem_of(record) -> str:
    """The file stem of a run's tables (``<stem>.md``, ``<stem>.csv``)."""
    return {"registration": "results", "lrf": "lrf_results"}.get(record["task"], record["task"])


def read_run(run_dir):
    """``(record, markdown)`` of an evaluation workdir."""
    path = os.path.join(run_dir, "run.json")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{run_dir} has no run.json: not an experiments.evaluate "
                                f"workdir (or one written before runs recorded themselves)")
    with open(path) as f:
        record = json.load(f)
    md_path = os.path.join(run_dir, f"{stem_of(record)}.md")
    if not os.path.isfile(md_path):
        found = sorted(glob.glob(os.path.join(run_dir, "*.md")))
        md_path = found[0] if found else None
    markdown = open(md_path).read() if md_path else ""
    for stem in BESIDE.get(record.get("task"), ()):
        path = os.path.join(run_dir, f"{stem}.md")
        if os.path.isfile(path):
            markdown = markdown.rstrip() + "\n\n" + open(path).read()
    return record, markdown


def data_of(record) -> str:
    """What a run evaluated on: the data root, rotated or not, its ground truth."""
    data = record.get("config", {}).get("data", {})
    where = data.get("root") or "the embedded synthetic data"
    if record.get("config", {}).get("rotate"):
        where += ", every scan rotated"
    if data.get("gt"):
        where += f", ground truth {data['gt']}"
    return where


def stamp(record) -> str:
    """One line: the command, the data, the bundles (steps and fingerprint: which weights),
    the date and wall time."""
    bundles = ", ".join(f"{k} `{v['path']}` ({v['steps_done']} steps"
                        + (f", fingerprint {v['fingerprint']})" if v.get("fingerprint") else ")")
                        for k, v in record.get("bundles", {}).items())
    took = f"{record['wall_s'] / 60:.0f} min"
    if record.get("resumed"):        # after an interruption, or for the unchanged bundles
        took = f"reusing the results an earlier run of it kept, the rest in {took}"
    return (f"`{record.get('command') or 'python -m experiments.evaluate'}`\n\n"
            f"Data: {data_of(record)}. Bundles: {bundles or 'none'}. Run {record['date']}, "
            f"{took}.")


def headline_table(run_dir) -> str:
    """Method rows of a registration run's means: FMR, inlier ratio, correct matches, RR,
    description time."""
    rows = report.read_means(run_dir, "results").values()
    out = ["| method | " + " | ".join(h for _, h, _ in HEADLINE) + " |",
           "|---" * (len(HEADLINE) + 1) + "|"]
    ms = [key for key, _, _ in HEADLINE].index("ms_per_keypoint")
    shared = False
    for r in rows:
        cells = []
        for key, _, fmt in HEADLINE:
            try:
                cells.append(fmt.format(float(r[key])))
            except (TypeError, ValueError):
                cells.append("")
        others = _number(r.get("others_cpu"))
        if others is not None and others > SHARED and cells[ms]:
            cells[ms] += f" (shared {others:.0%})"
            shared = True
        out.append(f"| {r['method']} | " + " | ".join(cells) + " |")
    if shared:
        out += ["", "shared N %: other processes used N % of the cores while the method "
                "described, so its time is longer than alone."]
    return "\n".join(out)


def _number(text) -> float | None:
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if value == value else None       # NaN: not recorded


def diagnostic(record) -> bool:
    """Whether a registration run reads the ground truth for a method (``lead_gt``, ...)."""
    from sphere_jax.features import registry
    if record.get("task") != "registration":
        return False
    methods = str(record.get("config", {}).get("methods") or "").split(",")
    return any(registry.resolve(m).kind == "diagnostic" for m in methods if m.strip())


def split_title(record, markdown):
    """``(title, body)`` of a run's markdown: its first heading, else the task's name."""
    lines = markdown.strip().splitlines()
    if lines and lines[0].startswith("#"):
        return lines[0].lstrip("# ").strip(), "\n".join(lines[1:])
    return record["task"], "\n".join(lines)


def heading(record, title) -> str:
    """A run's name in docs/results.md and on model cards: its table title and data, and
    whether it reads the ground truth for a diagnostic (then it stands beside the benchmark
    run of the same data, not in its place)."""
    return (f"{title} on {data_of(record)}"
            + (", with ground-truth-frame diagnostics" if diagnostic(record) else ""))


def section(record, markdown) -> str:
    title, body = split_title(record, markdown)
    body = re.sub(r"^# ", "### ", body, flags=re.M)
    return f"## {heading(record, title)}\n\n{stamp(record)}\n{body}\n"


# What an adaptation section compares, per task: (column, label, format); the change is that
# of the first.
COMPARED = {"registration": (("inlier_ratio", "inlier ratio", "{:.3f}"),
                             ("n_correct", "correct / pair", "{:.0f}"), ("rr", "RR", "{:.2f}")),
            "lrf": (("rep", "repeatability", "{:.3f}"),
                    ("mean_angle_deg", "mean angle (degrees)", "{:.1f}"))}


def adapted_bundles(before, after, after_dir):
    """``{kind: path}`` of the bundles the run ``after`` used adapted: the ones it names that
    ``before`` did not, and those it adapted itself first (``adapted_<kind>/bundle`` in its
    folder, an LRF run's test-time adaptation)."""
    out = {}
    for kind, rec in after.get("bundles", {}).items():
        own = os.path.join(after_dir, f"adapted_{kind}", "bundle")
        if os.path.isdir(own):
            out[kind] = own
        elif rec["path"] != before.get("bundles", {}).get(kind, {}).get("path"):
            out[kind] = rec["path"]
    return out


def adaptation_line(kind, path) -> str:
    """What an adapted bundle did: steps, minutes, the weights kept, the scans and scale."""
    from sphere_jax.bundles import model_card, store
    config = store.read_config(path)
    budget = float(config.train.get("time_budget_s", 0) or 0) / 60
    lines = model_card.read_metrics(os.path.join(path, model_card.METRICS))
    took = model_card.wall_time_s(lines, config.train.batch_size) / 60
    best = config.train.get("best_step")
    return (f"{kind}: {store.steps_done(config)} steps, {took:.1f} min of them"
            + (f" (budget {budget:g})" if budget else "")
            + ("" if best is None else ", the weights it started from kept (no better "
               "validation loss)" if best == 0 else f", weights of step {best}")
            + f", on `{config.data.root}` at voxel {config.data.voxel:g}, radius "
              f"{config.data.radius:g} (`{path}`)")


def budgets(kinds: dict) -> str:
    """The adapted bundles' time budgets for a title: ``, 10 min each`` or ``, compass 10 min,
    lead 5 min``; empty when none had one (a step count decided)."""
    from sphere_jax.bundles import store
    minutes = {k: float(store.read_config(p).train.get("time_budget_s", 0) or 0) / 60
               for k, p in sorted(kinds.items())}
    if not any(minutes.values()):
        return ""
    if len(set(minutes.values())) == 1:
        return f", {next(iter(minutes.values())):g} min" + (" each" if len(minutes) > 1 else "")
    return ", " + ", ".join(f"{k} {m:g} min" if m else f"{k} by steps"
                            for k, m in minutes.items())


def adaptation_section(before_dir, after_dir) -> str:
    """A run with the shipped bundles against the same run with adapted ones (registration:
    inlier ratio, correct matches, RR; LRF: repeatability, mean angle), method by method, and
    each adapted bundle's budget, steps and scans (read from the bundle)."""
    (before, _), (after, md) = read_run(before_dir), read_run(after_dir)
    if before["task"] != after["task"] or before["task"] not in COMPARED:
        raise ValueError(f"--adaptation compares two runs of one task among "
                         f"{', '.join(COMPARED)}; got {before['task']} and {after['task']}")
    compared = COMPARED[before["task"]]
    old, new = (report.read_means(d, stem_of(r)) for d, r in ((before_dir, before),
                                                               (after_dir, after)))
    cells = lambda r, key, fmt: fmt.format(float(r[key])) if r and r.get(key) else "–"
    head = [f"{label}: before | after" + (" | change" if i == 0 else "")
            for i, (_, label, _) in enumerate(compared)]
    out = ["| method | " + " | ".join(head) + " |", "|---" * (2 * len(compared) + 2) + "|"]
    first = compared[0][0]
    for method, b in old.items():
        a = new.get(method)
        change = f"{float(a[first]) / float(b[first]) - 1:+.0%}" if a and a.get(first) and \
            float(b[first]) > 0 else "–"
        row = []
        for i, (key, _, fmt) in enumerate(compared):
            row += [cells(b, key, fmt), cells(a, key, fmt)] + ([change] if i == 0 else [])
        out.append(f"| {method} | " + " | ".join(row) + " |")
    kinds = adapted_bundles(before, after, after_dir)
    adapted = [adaptation_line(kind, path) for kind, path in kinds.items()]
    title = split_title(after, md)[0].split(repeatability.ADAPTED)[0]   # said below instead
    if title[1:2].islower():                                 # "registration", not "lRF"
        title = title[0].lower() + title[1:]
    names = sorted(kinds)
    listed = " and ".join(filter(None, [", ".join(names[:-1]), names[-1]])) if names else "none"
    return (f"## Adaptation without labels, {listed} adapted{budgets(kinds)}: {title} on "
            f"{data_of(after)}"
            f"\n\nBefore: `{before.get('command')}`\n\nAfter: `{after.get('command')}`\n\n"
            f"Adapted bundles (no pose or ground truth read): " + "; ".join(adapted)
            + f". Runs {before['date']} and {after['date']}.\n\n" + "\n".join(out) + "\n")


def same_bundle(recorded, path) -> bool:
    """Whether the bundle at ``path`` is the one a run recorded (its fingerprint; for runs
    that recorded none, its steps): a card lists only its own bundle's evaluations."""
    from sphere_jax.bundles import store
    if recorded.get("fingerprint"):
        return recorded["fingerprint"] == store.fingerprint(path)
    return recorded.get("steps_done") == store.steps_done(store.read_config(path))


def readme_block(readme, name, content):
    """Replace the README's generated block ``name`` (between its begin and end markers)."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    text = open(readme).read()
    if begin not in text or end not in text:
        raise ValueError(f"{readme} has no {begin} ... {end} block")
    text = re.sub(re.escape(begin) + ".*?" + re.escape(end),
                  lambda _: f"{begin}\n{content}\n{end}", text, flags=re.S)
    io.atomic_write(readme, text.encode())             # the old README or the new, never half


SECTION = re.compile(r"^<!-- section: (.+?) -->$", re.M)
ADAPTATION = "adaptation "          # the key prefix of an adaptation section


def run_key(run_dir) -> str:
    """A run's section key in ``docs/results.md``: its folder, relative to the repository
    when inside it (so that ``runs/x`` and its absolute path name one section)."""
    path = os.path.abspath(run_dir)
    inside = os.path.commonpath([path, REPO]) == REPO
    return os.path.relpath(path, REPO) if inside else path


def merged_sections(old_text, sections, drop=()):
    """``[(key, markdown)]``: the sections of ``old_text`` (a results file this module wrote)
    in their order, each replaced by its namesake in ``sections``, those named in ``drop``
    left out (a :class:`ValueError` for one it does not hold). A new adaptation section goes
    after the last adaptation section, where a reader finds the others; other new keys are
    appended."""
    found = SECTION.split(old_text)[1:]           # [key, text, key, text, ...]
    merged = {k: t.strip() for k, t in zip(found[::2], found[1::2])}
    missing = [k for k in drop if k not in merged]
    if missing:
        raise ValueError(f"--drop: no section {missing[0]!r} (there are: {', '.join(merged)})")
    for key in drop:
        del merged[key]
    order = list(merged)
    for key, text in sections:
        if key not in merged:
            kin = [i for i, k in enumerate(order) if k.startswith(ADAPTATION)]
            at = kin[-1] + 1 if key.startswith(ADAPTATION) and kin else len(order)
            order.insert(at, key)
        merged[key] = text.strip()
    return [(k, merged[k]) for k in order]


def contents(sections):
    """Markdown list items linking each section's title (its first ``## `` line) by the anchor
    GitHub gives it (lower case, punctuation dropped, spaces to hyphens, ``-1``, ``-2`` for
    repeats)."""
    seen, items = {}, []
    for _, text in sections:
        title = next((line[3:].strip() for line in text.splitlines()
                      if line.startswith("## ")), None)
        if title is None:
            continue
        anchor = re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
        n = seen.get(anchor, 0)
        seen[anchor] = n + 1
        items.append(f"- [{title}](#{anchor}{f'-{n}' if n else ''})")
    return items


def publish(run_dirs, headline=None, results=RESULTS, readme=README, adaptations=(),
            targets=(), fresh=False, drop=(), classification=None):
    """Write the given runs' sections into ``results`` — replacing those runs' sections
    there and keeping the others but those keyed in ``drop`` (``fresh``: only the given
    ones), so that one rerun updates its own table — then the README's headline and targets
    blocks and the model cards. The headline run is published as a section too, so that the
    README, docs/results.md and the model cards never show two runs of one command."""
    if headline and run_key(headline) not in {run_key(d) for d in run_dirs}:
        run_dirs = [headline, *run_dirs]
    runs = [(d, *read_run(d)) for d in run_dirs]
    sections = [(run_key(d), section(record, md)) for d, record, md in runs]
    # An adaptation section is its adapted run's: published again with another 'before' run,
    # it replaces the one it had.
    sections += [(f"{ADAPTATION}{run_key(after)}", adaptation_section(before, after))
                 for before, after in adaptations]
    if not fresh and os.path.isfile(results):
        sections = merged_sections(open(results).read(), sections, drop)
    parts = ["# Results", "",
             "Generated by `python -m experiments.publish` from the evaluation runs' own files "
             "(`run.json`, the tables' markdown and CSV); do not edit. Each section names the "
             "command and the bundles that produced it.", "", *contents(sections), ""]
    for key, text in sections:
        parts += [f"<!-- section: {key} -->", text.strip(), ""]
    os.makedirs(os.path.dirname(results), exist_ok=True)
    io.atomic_write(results, ("\n".join(parts).rstrip() + "\n").encode())
    if headline:
        record, _ = read_run(headline)
        readme_block(readme, "headline", f"{headline_table(headline)}\n\n{stamp(record)}")
    if targets:
        from experiments import standing
        readme_block(readme, "targets", f"{standing.table(*targets)}\n\n`python -m "
                     f"experiments.publish ... --targets={','.join(targets)}` (the runs' "
                     f"commands and bundles: docs/results.md).")
    if classification:
        from experiments import standing
        readme_block(readme, "classification-targets",
                     f"{standing.classification_table(classification)}\n\n`python -m "
                     f"experiments.publish ... --classification={classification}` (its "
                     f"command, data and bundles: docs/results.md).")
    from sphere_jax.bundles import model_card
    for _, record, md in runs:
        for kind, b in record.get("bundles", {}).items():
            path = b["path"] if os.path.isabs(b["path"]) else os.path.join(REPO, b["path"])
            if os.path.isdir(path) and same_bundle(b, path):
                # One entry per task and data (redkitchen and the bunny share a title); a
                # diagnostic run beside the benchmark, not instead of it.
                title, body = split_title(record, md)
                model_card.add_evaluation(path, heading(record, title), body,
                                          record.get("command") or "", record["date"])
    return results


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("runs", nargs="*", help="experiments.evaluate workdirs")
    parser.add_argument("--headline", default=None, help="the run of the README's table")
    parser.add_argument("--adaptation", action="append", default=[],
                        help="BEFORE_RUN:AFTER_RUN, the same registration or LRF run with the "
                             "shipped and with adapted bundles")
    parser.add_argument("--targets", default=None,
                        help="MATCH,LOMATCH,ROTATED,LRF_KITCHEN,LRF_BUNNY[,LRF_KITCHEN_ADAPTED,"
                             "LRF_BUNNY_ADAPTED]: the redkitchen registration runs and the LRF "
                             "runs of the README's targets table (experiments/standing.py)")
    parser.add_argument("--classification", default=None,
                        help="the eval_classification run of the README's classification "
                             "targets (experiments/standing.py)")
    parser.add_argument("--drop", action="append", default=[],
                        help="a section of docs/results.md to remove, by its key (the "
                             "'<!-- section: KEY -->' line): a run that no longer stands")
    parser.add_argument("--fresh", action="store_true",
                        help="write only the given runs' sections (default: replace those and "
                             "keep the file's other sections)")
    args = parser.parse_args(argv)
    targets = args.targets.split(",") if args.targets else []
    if targets and len(targets) not in (5, 7):
        parser.error(f"--targets takes five runs, MATCH,LOMATCH,ROTATED,LRF_KITCHEN,"
                     f"LRF_BUNNY, and optionally the two LRF runs with adaptation; got "
                     f"{args.targets}")
    if not (args.runs or args.adaptation or targets or args.headline or args.drop
            or args.classification):
        parser.error("nothing to publish: give run folders, --adaptation, --targets, "
                     "--classification, --headline or --drop")
    pairs = [tuple(a.split(":")) for a in args.adaptation]
    if any(len(p) != 2 for p in pairs):
        parser.error(f"--adaptation takes BEFORE_RUN:AFTER_RUN, got {args.adaptation}")
    with cli.refusals():
        try:
            print(publish(args.runs, args.headline, adaptations=pairs, targets=targets,
                          fresh=args.fresh, drop=args.drop,
                          classification=args.classification))
        except (FileNotFoundError, ValueError) as e:
            cli.fail(e)


if __name__ == "__main__":
    main()
