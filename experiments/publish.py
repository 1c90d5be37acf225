"""Publish evaluation runs: every generated document is rendered from the committed records
of the runs (``docs/records``, :mod:`experiments.records`), so that a figure stands where its
record stands and nowhere else.

    python -m experiments.publish RUN_DIR [RUN_DIR ...] [--headline=RUN_DIR]
        [--adaptation=BEFORE_RUN:AFTER_RUN ...]
        [--targets=MATCH,LOMATCH,ROTATED,LRF,LRF_BUNNY[,GT_FRAMES]]
        [--classification=RUN_DIR] [--drop=NAME ...] [--fresh]
    python -m experiments.publish --check

Each RUN_DIR is an ``experiments.evaluate`` workdir: its ``run.json`` (command, config,
bundles, date) and CSV tables become its record ``docs/records/<folder name>/``, replacing an
older record of that name, and its section of ``docs/results.md`` (one table per run, methods
by metrics: the task's ``summary``). ``--headline`` (a registration run) fills the README's
``headline`` block; ``--targets`` its ``targets`` block (:mod:`experiments.standing`),
``--classification`` its ``classification-targets`` block; ``--registered`` (an
``experiments.registered`` workdir) adds its table to docs/registered.md; ``--bench`` (an
``experiments.bench --record`` folder) fills the suite's block of docs/performance.md.
``--adaptation`` compares a run with the shipped bundles and the same run with adapted ones
(``experiments.adapt``, or an LRF run's own ``adapt_steps``), method by method, and records
the comparison. ``--drop`` removes a record and its section, ``--fresh`` keeps only the runs
given.

Rendered from the records: docs/results.md, the README's blocks, the evaluations on the model
cards of the bundles in the package (a record's bundle fingerprint names the bundle it
measured) and the weights index. ``--check`` renders all of them and fails on any
difference from the files (a hand edit, or a record not published).
"""
from __future__ import annotations

import os
import re
from typing import NamedTuple

from experiments import cli, records, standing
from sphere_jax import paths
from sphere_jax.bundles import model_card, store
from sphere_jax.data.readers import io
from sphere_jax.eval import report, repeatability, tasks
from sphere_jax.models import shipped

REPO = records.REPO
HEADLINE = (("fmr", "FMR", "{:.2f}"), ("inlier_ratio", "inlier ratio", "{:.3f}"),
            ("n_correct", "correct / pair", "{:.0f}"), ("rr", "RR", "{:.2f}"),
            ("ms_per_keypoint", "ms / keypoint", "{:.2f}"))
BLOCKS = ("headline", "targets", "classification-targets")


class Outputs(NamedTuple):
    """Where the generated documents go."""
    results: str = os.path.join(REPO, "docs", "results.md")
    readme: str = os.path.join(REPO, "README.md")
    registered: str = os.path.join(REPO, "docs", "registered.md")
    performance: str = os.path.join(REPO, "docs", "performance.md")
    weights: str = paths.weights_root()        # each bundle's card, and the index


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


def headline_table(folder) -> str:
    """Method rows of a registration run's means: FMR, inlier ratio, correct matches, RR,
    description time."""
    return report.means_table(report.read_means(folder, "results"), HEADLINE)


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


def run_section(folder):
    """``(heading, section, tables, record)`` of a run record: its task's summary (the
    tables) under a heading that names its data, stamped with its command and bundles."""
    record = tasks.read_record(folder)
    title, body = split_title(record, records.summary(folder))
    name, body = heading(record, title), body.strip()
    return name, f"## {name}\n\n{stamp(record)}\n\n{body}\n", body, record


# What a comparison shows, per task: (column, label, format); the change is that of the first.
COMPARED = {"registration": (("inlier_ratio", "inlier ratio", "{:.3f}"),
                             ("n_correct", "correct / pair", "{:.0f}"), ("rr", "RR", "{:.2f}")),
            "lrf": (("rep", "repeatability", "{:.3f}"),
                    ("mean_angle_deg", "mean angle (degrees)", "{:.1f}"))}
STEMS = {"registration": "results", "lrf": "lrf_results"}


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
    minutes = {k: float(store.read_config(p).train.get("time_budget_s", 0) or 0) / 60
               for k, p in sorted(kinds.items())}
    if not any(minutes.values()):
        return ""
    if len(set(minutes.values())) == 1:
        return f", {next(iter(minutes.values())):g} min" + (" each" if len(minutes) > 1 else "")
    return ", " + ", ".join(f"{k} {m:g} min" if m else f"{k} by steps"
                            for k, m in minutes.items())


def comparison(before_dir, after_dir) -> dict:
    """The record of a run with the shipped bundles against the same run with adapted ones:
    both runs' commands, dates and mean rows of :data:`COMPARED`, and what each adapted bundle
    did (read from the bundle, which the record outlives)."""
    before, after = tasks.read_record(before_dir), tasks.read_record(after_dir)
    if before["task"] != after["task"] or before["task"] not in COMPARED:
        raise ValueError(f"--adaptation compares two runs of one task among "
                         f"{', '.join(COMPARED)}; got {before['task']} and {after['task']}")
    task = before["task"]
    old, new = (report.read_means(d, STEMS[task]) for d in (before_dir, after_dir))
    keys = [key for key, _, _ in COMPARED[task]]
    values = lambda row: {k: report.number(row.get(k)) if row else None for k in keys}
    rows = []
    for method, b in old.items():
        a, first = new.get(method), keys[0]
        change = (float(a[first]) / float(b[first]) - 1 if a and report.number(a.get(first))
                  is not None and float(b[first]) > 0 else None)
        rows.append({"method": method, "before": values(b), "after": values(a),
                     "change": change})
    kinds = adapted_bundles(before, after, after_dir)
    title = split_title(after, records.summary(after_dir))[0]
    title = title.split(repeatability.ADAPTED)[0]                # said below instead
    names = sorted(kinds)
    return {"task": task, "title": title, "data": data_of(after),
            "adapted": " and ".join(filter(None, [", ".join(names[:-1]), names[-1]]))
            if names else "none", "budgets": budgets(kinds),
            "lines": [adaptation_line(kind, path) for kind, path in kinds.items()],
            "before": {"command": before.get("command"), "date": before["date"]},
            "after": {"command": after.get("command"), "date": after["date"]},
            "rows": rows}


def comparison_section(c: dict) -> str:
    """A comparison record as markdown: the methods' figures before | after, the change of the
    first, and the adapted bundles."""
    compared = COMPARED[c["task"]]
    head = [f"{label}: before | after" + (" | change" if i == 0 else "")
            for i, (_, label, _) in enumerate(compared)]
    out = ["| method | " + " | ".join(head) + " |", "|---" * (2 * len(compared) + 2) + "|"]
    cell = lambda v, fmt: "–" if v is None else fmt.format(v)
    for r in c["rows"]:
        row = []
        for i, (key, _, fmt) in enumerate(compared):
            row += [cell(r["before"].get(key), fmt), cell(r["after"].get(key), fmt)]
            row += [cell(r["change"], "{:+.0%}")] if i == 0 else []
        out.append(f"| {r['method']} | " + " | ".join(row) + " |")
    title = c["title"]
    if title[1:2].islower():                                 # "registration", not "lRF"
        title = title[0].lower() + title[1:]
    return (f"## Adaptation without labels, {c['adapted']} adapted{c['budgets']}: {title} on "
            f"{c['data']}\n\nBefore: `{c['before']['command']}`\n\nAfter: "
            f"`{c['after']['command']}`\n\nAdapted bundles (no pose or ground truth read): "
            + "; ".join(c["lines"]) + f". Runs {c['before']['date']} and "
            f"{c['after']['date']}.\n\n" + "\n".join(out) + "\n")


def replace_block(text, name, content, what="the README") -> str:
    """``text`` (the README's) with its generated block ``name`` (between its begin and end
    markers) holding ``content``."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    if begin not in text or end not in text:
        raise ValueError(f"{what} has no {begin} ... {end} block")
    return re.sub(re.escape(begin) + ".*?" + re.escape(end),
                  lambda _: f"{begin}\n{content}\n{end}", text, flags=re.S)


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


def bench_block(bench: dict) -> str:
    """A benchmark record as its table — a field that holds a dict (register's stages) as a
    table of its own, one line per record — and the line that says where it ran."""
    from experiments.benchmarks import common
    rows = [{k: "" if v is None else v for k, v in r.items()} for r in bench["records"]]
    nested = [c for c in dict.fromkeys(c for r in rows for c in r)
              if any(isinstance(r.get(c), dict) for r in rows)]
    flat = [{k: v for k, v in r.items() if k not in nested} for r in rows]
    parts = [common.format_table(flat)]
    label = next(iter(flat[0])) if flat and flat[0] else None
    for c in nested:
        parts.append(f"`{c}`:\n\n" + common.format_table(
            [{label: r.get(label), **(r.get(c) or {})} for r in rows if r.get(c)]))
    return ("\n\n".join(parts) + f"\n\n`{bench['command']}` on {bench['machine']}, "
            f"{bench['date']} (record `docs/records/bench-{bench['suite']}`).")


def bundles_in(weights_root) -> dict:
    """``{fingerprint: bundle folder}`` of the bundles under ``weights_root``."""
    out = {}
    for folder in sorted(os.listdir(weights_root)) if os.path.isdir(weights_root) else ():
        path = os.path.join(weights_root, folder, "bundle")
        if store.is_bundle(path):
            out[store.fingerprint(path)] = path
    return out


def render(root=records.ROOT, outputs=Outputs()) -> dict:
    """``{path: text}`` of every document the records generate: docs/results.md, the
    README (its blocks filled), the weights index and, for each bundle under the weights
    root, its ``evaluations.json`` and model card."""
    index = records.read_index(root)
    folder = lambda name: records.folder(name, root)
    sections, cards = [], {}
    prints = bundles_in(outputs.weights)
    for name in index["sections"]:
        if name.startswith(records.ADAPTATION):
            sections.append((name, comparison_section(records.read_comparison(name, root))))
            continue
        title, text, body, record = run_section(folder(name))
        sections.append((name, text))
        for b in record.get("bundles", {}).values():
            if b.get("fingerprint") in prints:
                entries = cards.setdefault(prints[b["fingerprint"]], {})
                if title in entries:
                    raise ValueError(f"two records give {title!r} for one bundle: drop one")
                entries[title] = {"command": record.get("command") or "", "table": body,
                                  "date": record["date"]}
    parts = ["# Results", "",
             "Generated by `python -m experiments.publish` from the runs' records in "
             "`docs/records` (their `run.json` and CSV tables); do not edit. Each section names "
             "the command and the bundles that produced it.", "", *contents(sections), ""]
    for name, text in sections:
        parts += [f"<!-- section: {name} -->", text.strip(), ""]
    out = {outputs.results: "\n".join(parts).rstrip() + "\n"}
    readme = on_disk(outputs.readme)
    if index["headline"]:
        record = tasks.read_record(folder(index["headline"]))
        readme = replace_block(readme, "headline", f"{headline_table(folder(index['headline']))}"
                                                   f"\n\n{stamp(record)}")
    if index["targets"]:
        table = standing.table(*map(folder, index["targets"]))
        names = ", ".join(index["targets"])
        readme = replace_block(readme, "targets", f"{table}\n\nFrom the records {names} "
                               f"(docs/records; their commands and bundles: docs/results.md).")
    if index["classification"]:
        readme = replace_block(
            readme, "classification-targets",
            f"{standing.classification_table(folder(index['classification']))}\n\nFrom the "
            f"record {index['classification']} (its command, data and bundles: "
            f"docs/results.md).")
    out[outputs.readme] = readme
    if index["bench"]:
        text = on_disk(outputs.performance)
        for name in index["bench"]:
            text = replace_block(text, name, bench_block(records.read_bench(name, root)),
                                 what=outputs.performance)
        out[outputs.performance] = text
    if index["registered"]:
        from sphere_jax.eval import registered
        parts = [registered.PAGE]
        for name in index["registered"]:
            record = tasks.read_record(folder(name))
            body = split_title(record, records.summary(folder(name)))[1].strip()
            parts += [f"<!-- section: {name} -->", f"## {'; '.join(record['data'])}", "",
                      body, ""]
        out[outputs.registered] = "\n".join(parts).rstrip() + "\n"
    for path in prints.values():
        entries = cards.get(path, {})
        out[os.path.join(path, model_card.EVALUATIONS)] = model_card.evaluations_text(entries)
        out[os.path.join(path, model_card.CARD)] = model_card.text(path, entries)
    if os.path.isdir(outputs.weights):
        out[os.path.join(outputs.weights, "README.md")] = model_card.index_text(
            outputs.weights, shipped.SHIPPED)
    return out


def on_disk(path) -> str | None:
    """A file's text; None when it is absent."""
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return f.read()


def differences(rendered: dict) -> list[str]:
    """The paths of ``rendered`` whose file on disk differs (or is absent)."""
    return [p for p, text in rendered.items() if on_disk(p) != text]


def publish(run_dirs=(), headline=None, adaptations=(), targets=(), classification=None,
            fresh=False, drop=(), root=records.ROOT, outputs=Outputs(),
            registered=(), bench=()) -> list[str]:
    """Record the given runs (and comparisons ``(before_dir, after_dir)``), update the index
    — a run published again keeps its place, a new one goes last (a comparison after the
    other comparisons), ``drop`` names records to remove, ``fresh`` keeps only these — and
    write every document the records render. Returns the paths that changed."""
    index = records.read_index(root)
    missing = [n for n in drop if n not in index["sections"] + index["registered"]]
    if missing:
        raise ValueError(f"--drop: no record {missing[0]!r} (there are: "
                         f"{', '.join(index['sections'] + index['registered'])})")
    index["registered"] = [n for n in index["registered"] if n not in drop]
    os.makedirs(root, exist_ok=True)
    given = [records.save(d, root) for d in run_dirs]
    if headline:
        index["headline"] = records.save(headline, root)
    if targets:
        index["targets"] = [records.save(d, root) for d in targets]
    if classification:
        index["classification"] = records.save(classification, root)
    for d in bench:
        name = records.save_bench(d, root)
        index["bench"] = [n for n in index["bench"] if n != name] + [name]
    for d in registered:             # docs/registered.md, a page of its own
        name = records.save(d, root)
        index["registered"] = [n for n in index["registered"] if n != name] + [name]
    compared = [records.save_comparison(records.name_of(after),
                                        comparison(before, after), root)
                for before, after in adaptations]
    order = [] if fresh else [n for n in index["sections"] if n not in drop]
    for name in [*given, index["headline"], *index["targets"], index["classification"]]:
        if name and name not in order:
            order.append(name)
    for name in compared:
        if name not in order:
            kin = [i for i, n in enumerate(order) if n.startswith(records.ADAPTATION)]
            order.insert(kin[-1] + 1 if kin else len(order), name)
    index["sections"] = order
    records.write_index(index, root)
    rendered = render(root, outputs)
    changed = differences(rendered)
    for path in changed:
        io.atomic_write(path, rendered[path].encode())
    return changed


def main(argv=None):
    parser = cli.ArgumentParser(doc=__doc__)
    parser.add_argument("runs", nargs="*", help="experiments.evaluate workdirs")
    parser.add_argument("--headline", default=None, help="the run of the README's table")
    parser.add_argument("--adaptation", action="append", default=[],
                        help="BEFORE_RUN:AFTER_RUN, the same registration or LRF run with the "
                             "shipped and with adapted bundles")
    parser.add_argument("--targets", default=None,
                        help="MATCH,LOMATCH,ROTATED,LRF_KITCHEN,LRF_BUNNY[,GT_FRAMES[,"
                             "LRF_KITCHEN_ADAPTED,LRF_BUNNY_ADAPTED]]: the runs of the README's "
                             "targets table (experiments/standing.py)")
    parser.add_argument("--classification", default=None,
                        help="the eval_classification run of the README's classification "
                             "targets (experiments/standing.py)")
    parser.add_argument("--registered", action="append", default=[],
                        help="an experiments.registered workdir: its table in "
                             "docs/registered.md")
    parser.add_argument("--bench", action="append", default=[],
                        help="an experiments.bench --record folder: its table in its block of "
                             "docs/performance.md")
    parser.add_argument("--drop", action="append", default=[],
                        help="a record to remove with its section, by name (docs/records)")
    parser.add_argument("--fresh", action="store_true",
                        help="keep only the given runs' sections (default: replace those and "
                             "keep the others)")
    parser.add_argument("--check", action="store_true",
                        help="render every generated document from the records and fail on "
                             "any difference from the files")
    args = parser.parse_args(argv)
    targets = args.targets.split(",") if args.targets else []
    if targets and len(targets) not in (5, 6, 8):
        parser.error(f"--targets takes five runs, MATCH,LOMATCH,ROTATED,LRF_KITCHEN,"
                     f"LRF_BUNNY, optionally GT_FRAMES and then the two LRF runs with "
                     f"adaptation; got {args.targets}")
    pairs = [tuple(a.split(":")) for a in args.adaptation]
    if any(len(p) != 2 for p in pairs):
        parser.error(f"--adaptation takes BEFORE_RUN:AFTER_RUN, got {args.adaptation}")
    asked = (args.runs or pairs or targets or args.headline or args.drop or args.classification
             or args.registered or args.bench)
    if args.check and asked:
        parser.error("--check takes no runs: it renders the committed records")
    if not (asked or args.check):
        parser.error("nothing to publish: give run folders, --adaptation, --targets, "
                     "--classification, --headline or --drop (or --check)")
    with cli.refusals():
        try:
            if args.check:
                stale = differences(render())
                for path in stale:
                    print(f"differs from its records: {os.path.relpath(path, REPO)}")
                if stale:
                    cli.fail("generated documents differ from docs/records: run "
                             "`python -m experiments.publish` (with no hand edits)")
                print(f"every generated document equals its records "
                      f"({len(records.read_index()['sections'])} sections)")
                return
            for path in publish(args.runs, args.headline, pairs, targets,
                                args.classification, args.fresh, args.drop,
                                registered=args.registered, bench=args.bench):
                print(f"wrote {os.path.relpath(path, REPO)}")
        except (FileNotFoundError, ValueError) as e:
            cli.fail(e)


if __name__ == "__main__":
    main()
