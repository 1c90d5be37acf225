"""A bundle's model card, generated from the bundle's own files, never written by hand.

``bundle/MODEL_CARD.md`` and ``bundle/validation_curve.png`` are rendered from

* ``config.json`` and ``training_data.json`` (the network, the recipe, the data),
* ``metrics.jsonl`` (the training log: steps, wall time, the validation curve), which
  training copies into the bundle, and
* ``evaluations.json``: the published evaluations of this bundle (a table, the command and
  the date of each run), which ``experiments.publish`` sets from docs/records.

Training calls :func:`write` when it writes a bundle; publishing calls
:func:`set_evaluations`, which renders the card again. ``python -m experiments.model_card
BUNDLE`` re-renders one.
"""
from __future__ import annotations

import json
import os

from sphere_jax import files
from sphere_jax.bundles import store
from sphere_jax.bundles import whitening

CARD = "MODEL_CARD.md"
CURVE = "validation_curve.png"
METRICS = "metrics.jsonl"
EVALUATIONS = "evaluations.json"


def read_metrics(path) -> list[dict]:
    """The lines of a ``metrics.jsonl`` ([] when there is none)."""
    if not os.path.isfile(path):
        return []
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def wall_time_s(lines, batch_size) -> float:
    """Seconds the training loop ran, from the log itself: each line's patches per second
    covers the patches since the line before."""
    total, last = 0.0, 0
    for line in lines:
        pps = line.get("patches_per_s") or 0
        if pps > 0:
            total += (line["step"] - last) * batch_size / pps
        last = line["step"]
    return total


def validation_curve(lines):
    """``(steps, {metric: values})`` of the validation metrics in the log."""
    rows = [ln for ln in lines if "val_loss" in ln]
    keys = sorted({k for ln in rows for k in ln if k.startswith("val_")})
    return [ln["step"] for ln in rows], {k: [ln.get(k) for ln in rows] for k in keys}


def plot_curve(lines, path, title):
    """The training and validation loss against the step, as a PNG at ``path``."""
    # A Figure of its own, not pyplot's: training inside a notebook keeps its inline backend.
    from matplotlib.figure import Figure
    steps, val = validation_curve(lines)
    fig = Figure(figsize=(6, 3.5), dpi=100)
    ax = fig.subplots()
    trained = [ln for ln in lines if "loss" in ln]      # not a fine-tune's evaluation before
    ax.plot([ln["step"] for ln in trained], [ln["loss"] for ln in trained], lw=0.8, alpha=0.6,
            label="training loss (batch)")
    if steps:
        ax.plot(steps, val["val_loss"], "o-", lw=1.5, label="validation loss")
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    with files.replacing(path, ".png") as tmp:
        fig.savefig(tmp)


def evaluations_text(evaluations: dict) -> str:
    """``evaluations.json`` of ``{name: {'command', 'table', 'date'}}``."""
    return json.dumps(evaluations, indent=1, sort_keys=True) + "\n"


def set_evaluations(bundle_dir, evaluations: dict):
    """Replace the bundle's evaluations (``{name: {'command', 'table', 'date'}}``, from the
    published records: ``experiments.publish``) and render the card again."""
    files.atomic_write(os.path.join(str(bundle_dir), EVALUATIONS),
                       evaluations_text(evaluations))
    render(bundle_dir)


def write(bundle_dir, metrics_path, command=None):
    """Copy the training log into the bundle, note the command, render the card."""
    bundle_dir = str(bundle_dir)
    if metrics_path and os.path.isfile(metrics_path) and \
            os.path.abspath(metrics_path) != os.path.abspath(os.path.join(bundle_dir, METRICS)):
        with open(metrics_path) as f:
            files.atomic_write(os.path.join(bundle_dir, METRICS), f.read())
    if command:
        files.atomic_write(os.path.join(bundle_dir, "command.txt"), command.strip() + "\n")
    return render(bundle_dir)


def render(bundle_dir):
    """Write ``MODEL_CARD.md`` (and the curve's PNG) from the bundle's files."""
    bundle_dir = str(bundle_dir)
    config = store.read_config(bundle_dir)
    lines = read_metrics(os.path.join(bundle_dir, METRICS))
    if validation_curve(lines)[0]:
        plot_curve(lines, os.path.join(bundle_dir, CURVE),
                   f"{config.model}:{config.get('size', '')}, {store.steps_done(config)} steps")
    files.atomic_write(os.path.join(bundle_dir, CARD), text(bundle_dir))
    return os.path.join(bundle_dir, CARD)


def read_evaluations(bundle_dir) -> dict:
    return store.read_json(bundle_dir, EVALUATIONS)


def text(bundle_dir, evaluations=None) -> str:
    """``MODEL_CARD.md`` of the bundle, with ``evaluations`` (default: its
    ``evaluations.json``)."""
    bundle_dir = str(bundle_dir)
    config = store.read_config(bundle_dir)
    data = store.read_training_data(bundle_dir)
    lines = read_metrics(os.path.join(bundle_dir, METRICS))
    command_file = os.path.join(bundle_dir, "command.txt")
    command = open(command_file).read().strip() if os.path.isfile(command_file) else None
    train = config.train
    done = store.steps_done(config)
    out = [f"# {config.model} ({config.get('size', '')})", ""]
    out += ["Generated from this bundle's files by `sphere_jax.bundles.model_card`; do not "
            "edit.", ""]
    out += ["## Training", ""]
    if command:
        out += ["```bash", command, "```", ""]
    kwargs = json.dumps(config.get("model_kwargs", {}).to_dict()
                        if hasattr(config.get("model_kwargs", {}), "to_dict")
                        else config.get("model_kwargs", {}))
    out += [f"- network: `{config.model}` {kwargs}"]
    sched = train.get("schedule", "constant")
    rate = f"{train.learning_rate:g}"
    if sched == "warmup_cosine" and float(train.final_lr_fraction) == 1.0:
        rate += f" after {train.warmup_steps} warm-up steps, then constant"
    elif sched == "warmup_cosine":
        rate += (f", {train.warmup_steps} warm-up steps, cosine decay to "
                 f"{train.final_lr_fraction:g}× at step {train.steps}")
    planned = (f"within a {float(train.time_budget_s) / 60:g}-minute budget"
               if train.get("budget_ends") else f"of {train.steps} planned")
    out += [f"- steps: {done} {planned} × batch {train.batch_size}; "
            f"learning rate {rate} (Adam)"]
    if train.get("best_step") is not None:
        out += [f"- weights of step {train.best_step}, the best validation loss (early "
                f"stopping; step 0: the weights it started from)"]
    if lines:
        out += [f"- wall time of the training loop: "
                f"{wall_time_s(lines, train.batch_size) / 60:.1f} min"]
    folders = data.get("folders", {})
    out += ["- data: " + ", ".join(f"`{k}` ({_counted(v, data)})" if v is not None
                                   else f"`{k}`" for k, v in folders.items())]
    if "keypoints" in data:
        out += [f"- keypoints: {data['keypoints'].get('train')} training, "
                f"{data['keypoints'].get('val')} held out for the validation loss"]
    scenes = data.get("evaluation_scenes", [])
    out += [f"- evaluation scenes in the training data: {', '.join(scenes) or 'none'}"]
    for source, fit in whitening.read_statement(bundle_dir).items():
        out += [f"- descriptor whitening `{source}` ({fit['frames']} frames): "
                f"{fit['keypoints']} keypoints of {len(fit['scans'])} training scans, "
                f"{fit['dimensions_kept']} directions kept; `{fit['command']}`"
                + (f"; kept from `{fit['kept_from']}`, fitted for its weights"
                   if fit.get("kept_from") else "")]
    steps, val = validation_curve(lines)
    if steps:
        out += ["", "## Validation curve", "", f"![validation curve]({CURVE})", ""]
        keys = list(val)
        out += ["| step | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
        for i, s in enumerate(steps):
            out += [f"| {s} | " + " | ".join(f"{val[k][i]:.4g}" if val[k][i] is not None
                                              else "" for k in keys) + " |"]
    evaluations = read_evaluations(bundle_dir) if evaluations is None else evaluations
    if evaluations:
        out += ["", "## Evaluations", ""]
        for name, ev in sorted(evaluations.items()):
            out += [f"### {name}", "", f"{ev['date']}:", "", "```bash", ev["command"], "```",
                    "", ev["table"].strip(), ""]
    return "\n".join(out).rstrip() + "\n"


def _counted(n, data) -> str:
    """``n`` scans or shapes of a training-data statement: '1 scan', '12 scans'."""
    unit = "shape" if data.get("kind") == "shapes" else "scan"
    return f"{n} {unit}{'s' * (n != 1)}"


def _trained_on(config, data) -> str:
    """The training data in one cell: the config's ``data.root`` as it was given (the card
    lists every folder) and how many scans or shapes it held."""
    counts = [v for v in data.get("folders", {}).values() if v is not None]
    total = f" ({_counted(sum(counts), data)})" if counts else ""
    root = str(config.data.get("root", "")) or ", ".join(data.get("folders", {}))
    return f"`{root}`{total}"


def weights_index(root, shipped) -> str:
    """Write the shipped bundles' index, ``root/README.md`` (:func:`index_text`); returns its
    path."""
    files.atomic_write(os.path.join(root, "README.md"), index_text(root, shipped))
    return os.path.join(root, "README.md")


def index_text(root, shipped) -> str:
    """The shipped bundles' index (``sphere_jax/weights/README.md``), from their files:
    ``shipped`` maps each name to its :class:`~sphere_jax.models.shipped.Shipped` row
    (folder under ``root``, recipe)."""
    out = ["# Shipped bundles", "",
           "Generated by `python -m experiments.model_card --index` from the bundles' files; do "
           "not edit. `sphere_jax.load_bundle(NAME)` loads one; each folder's "
           "`bundle/MODEL_CARD.md` has its validation curve and evaluations. The last column is "
           "the command that ran; `python -m experiments.train --config=RECIPE:mid "
           "--workdir=W` trains the same config from scratch (`tests/test_weights.py` checks "
           "it).", "",
           "| name | folder | network | steps done / planned × batch | trained on | recipe | "
           "command that ran |",
           "|---|---|---|---|---|---|---|"]
    for kind, row in sorted(shipped.items()):
        folder = row.folder
        path = os.path.join(root, folder, "bundle")
        if not store.is_bundle(path):
            continue
        config = store.read_config(path)
        data = store.read_training_data(path)
        kwargs = config.get("model_kwargs", {})
        kwargs = kwargs.to_dict() if hasattr(kwargs, "to_dict") else kwargs
        net = ", ".join(f"{k}={tuple(v) if isinstance(v, list) else v}" for k, v in
                        kwargs.items() if "decoder" not in k)
        done = store.steps_done(config)
        command_file = os.path.join(path, "command.txt")
        command = open(command_file).read().strip() if os.path.isfile(command_file) else ""
        recipe = f"`{row.recipe}:mid`"
        out.append(f"| {kind} | `{folder}` | {net} | {done} / {config.train.steps} × "
                   f"{config.train.batch_size} | {_trained_on(config, data)} | {recipe} | "
                   f"`{command}` |")
    return "\n".join(out) + "\n"
