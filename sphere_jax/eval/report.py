"""Benchmark results as files: CSV for scripts, markdown tables like the seed's (rows =
methods, columns = scenes + mean), and the PNG plots (matplotlib, headless)."""
from __future__ import annotations

import csv
import io
import os

import numpy as np

from sphere_jax.data.readers.io import atomic_write

REGISTRATION_COLUMNS = ("method", "scene", "pairs", "fmr", "inlier_ratio", "n_correct",
                        "rre_deg", "rte_m", "ms_per_keypoint", "others_cpu", "rr")
# Columns that measure the machine rather than the method: two runs of one config differ here.
TIMING_COLUMNS = ("ms_per_keypoint", "others_cpu")
LRF_COLUMNS = ("method", "scene", "pairs", "rep", "mean_angle_deg")
# Titles are templates: ``{tau1}``, ``{tau2}``, ``{rho}``... are the run's own settings
# (:func:`titled`).
REGISTRATION_TABLES = (("fmr", "Feature-match recall (τ1 = {tau1:g} m, τ2 = {tau2:g})",
                        "{:.3f}"),
                       ("inlier_ratio", "Inlier ratio", "{:.3f}"),
                       ("n_correct", "Correct correspondences per pair", "{:.1f}"),
                       ("rr", "Registration recall (RANSAC; RRE < {rre:g}°, RTE < {rte:g} m)",
                        "{:.3f}"),
                       ("rre_deg", "RRE of registered pairs (degrees)", "{:.2f}"),
                       ("rte_m", "RTE of registered pairs (m)", "{:.3f}"),
                       ("ms_per_keypoint", "Description time (ms per keypoint)", "{:.3f}"),
                       ("others_cpu", "Share of the cores other processes used while it "
                        "described (– : not recorded)", "{:.2f}"))
LRF_TABLES = (("rep", "LRF repeatability (ρ = {rho:.2f})", "{:.3f}"),
              ("mean_angle_deg", "Mean angle between corresponding LRFs (degrees)", "{:.1f}"))


def titled(tables, **settings):
    """``tables`` with their titles filled in from the run's ``settings``."""
    return tuple((key, title.format(**settings), fmt) for key, title, fmt in tables)


def _nanmean(values):
    values = np.asarray([v for v in values], float)
    return float(np.nanmean(values)) if np.isfinite(values).any() else float("nan")


def with_means(rows, columns):
    """``rows`` (dicts with method, scene, ...) plus one ``mean`` row per method: pairs summed,
    every other number averaged over scenes."""
    out = list(rows)
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        mean = {"method": method, "scene": "mean", "pairs": sum(r["pairs"] for r in mine)}
        mean.update({c: _nanmean([r[c] for r in mine]) for c in columns[3:]})
        out.append(mean)
    return out


def to_csv(rows, columns):
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore",
                            lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({c: (f"{r[c]:.6g}" if isinstance(r[c], float) else r[c])
                         for c in columns})
    return buf.getvalue()


def _cell(v, fmt):
    if isinstance(v, (float, np.floating)):
        return "–" if not np.isfinite(v) else fmt.format(v)
    return str(v)


def table(rows, columns, headers=None, fmt="{:.3f}"):
    """A markdown table with one line per row (dicts), columns padded so that it also reads
    in a terminal; floats formatted by ``fmt`` (NaN as –)."""
    headers = list(headers or columns)
    cells = [[_cell(r[c], fmt) for c in columns] for r in rows]
    widths = [max(len(h), *(len(row[i]) for row in cells)) for i, h in enumerate(headers)]
    line = lambda vals: "| " + " | ".join(v.ljust(w) for v, w in zip(vals, widths)) + " |"
    return "\n".join([line(headers), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
                     + [line(r) for r in cells])


def pivot_table(rows, row_key, col_key, value_key, fmt="{:.3f}", cols=None):
    """A markdown table of one value: one line per ``row_key``, one column per ``col_key``
    (in first-seen order unless ``cols``); missing cells as –."""
    cols = list(cols or dict.fromkeys(r[col_key] for r in rows))
    names = list(dict.fromkeys(r[row_key] for r in rows))
    cell = {(r[row_key], r[col_key]): r[value_key] for r in rows}
    lines = [f"| {row_key} | " + " | ".join(map(str, cols)) + " |", "|---" * (len(cols) + 1)
             + "|"]
    for n in names:
        lines.append(f"| {n} | " + " | ".join(_cell(cell.get((n, c), float("nan")), fmt)
                                             for c in cols) + " |")
    return "\n".join(lines)


def markdown_table(rows, key, fmt):
    """Rows = methods, columns = scenes (then mean) for one metric."""
    scenes = list(dict.fromkeys(r["scene"] for r in rows if r["scene"] != "mean")) + ["mean"]
    return pivot_table(rows, "method", "scene", key, fmt, scenes)


def write(workdir, stem, rows, columns, md):
    """``<stem>.csv`` (``columns`` of ``rows``) and ``<stem>.md`` (``md``) in ``workdir``."""
    os.makedirs(workdir, exist_ok=True)
    atomic_write(os.path.join(workdir, f"{stem}.csv"), to_csv(rows, columns).encode())
    atomic_write(os.path.join(workdir, f"{stem}.md"), md.encode())
    return md


def read_means(workdir, stem) -> dict:
    """``{method: its mean row}`` of ``<stem>.csv`` in ``workdir`` (values as strings)."""
    with open(os.path.join(workdir, f"{stem}.csv")) as f:
        return {r["method"]: r for r in csv.DictReader(f) if r["scene"] == "mean"}


def read_rows(workdir, stem) -> list[dict]:
    """Every row of ``<stem>.csv`` in ``workdir`` (values as strings); [] when it is absent."""
    path = os.path.join(workdir, f"{stem}.csv")
    if not os.path.isfile(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def means_of(folder, stem):
    """``(scenes, {method: mean row}, pairs)`` of ``<stem>.csv`` in a run's folder: what a
    published summary states above and below its table."""
    rows = read_rows(folder, stem)
    scenes = list(dict.fromkeys(r["scene"] for r in rows if r["scene"] != "mean"))
    means = read_means(folder, stem)
    return scenes, means, max(int(float(r["pairs"])) for r in means.values())


def number(text) -> float | None:
    """A CSV cell as a float; None for an empty, unparsable or NaN cell (not recorded)."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if value == value else None


# A description time measured while other processes used more than this share of the cores
# is marked as shared (sphere_jax/eval/timing.py).
SHARED = 0.1


def means_table(means: dict, columns) -> str:
    """One markdown line per method of ``means`` (``{method: mean row}``, :func:`read_means`),
    one column per ``(key, header, fmt)`` of ``columns``; an ``ms_per_keypoint`` measured
    while other processes used more than :data:`SHARED` of the cores is marked, and said
    so below the table."""
    out = ["| method | " + " | ".join(h for _, h, _ in columns) + " |",
           "|---" * (len(columns) + 1) + "|"]
    shared = False
    for method, row in means.items():
        cells = []
        for key, _, fmt in columns:
            value = number(row.get(key))
            cell = "–" if value is None else fmt.format(value)
            others = number(row.get("others_cpu"))
            if key == "ms_per_keypoint" and value is not None and others is not None \
                    and others > SHARED:
                cell += f" (shared {others:.0%})"
                shared = True
            cells.append(cell)
        out.append(f"| {method} | " + " | ".join(cells) + " |")
    if shared:
        out += ["", "shared N %: other processes used N % of the cores while the method "
                "described, so its time is longer than alone."]
    return "\n".join(out)


def markdown_report(rows, tables, title):
    parts = [f"# {title}"]
    for key, caption, fmt in tables:
        parts += ["", f"**{caption}**", "", markdown_table(rows, key, fmt)]
    return "\n".join(parts) + "\n"


def write_tables(workdir, rows, columns, tables, stem, title):
    """``<stem>.csv`` and ``<stem>.md`` in ``workdir``; returns the markdown."""
    rows = with_means(rows, columns)
    return write(workdir, stem, rows, columns, markdown_report(rows, tables, title))


def pyplot():
    """matplotlib.pyplot on the headless Agg backend (imported on first use)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_fmr_curve(curve: dict, tau2_values, path, title="Feature-match recall vs τ2"):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 3.6), dpi=120)
    for method, fmr in curve.items():
        ax.plot(tau2_values, fmr, marker=".", label=method)
    ax.set(xlabel="inlier-ratio threshold τ2", ylabel="feature-match recall", ylim=(-0.02, 1.02),
           title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_repeatability(points_Nx3, keypoints_Kx3, repeatable_K, path, title, max_points=20000,
                       seed=0):
    """Scan i in grey, its overlap keypoints green (repeatable LRF) or red (not), seen from
    the sensor side (the seed's Fig. 3.4)."""
    plt = pyplot()
    rng = np.random.default_rng(seed)
    if len(points_Nx3) > max_points:
        points_Nx3 = points_Nx3[rng.choice(len(points_Nx3), max_points, replace=False)]
    fig = plt.figure(figsize=(5, 4.4), dpi=120)
    ax = fig.add_subplot(projection="3d")
    ax.scatter(*points_Nx3.T, s=0.3, c="0.7", alpha=0.4, depthshade=False)
    for mask, colour, label in ((repeatable_K, "tab:green", "repeatable"),
                                (~repeatable_K, "tab:red", "not repeatable")):
        ax.scatter(*keypoints_Kx3[mask].T, s=4, c=colour, depthshade=False,
                   label=f"{label} ({int(mask.sum())})")
    ax.view_init(elev=-70, azim=-90)                           # camera looks along +z
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)
    ax.legend(loc="lower left", fontsize=7, markerscale=3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_recognition(rows, curves, workdir):
    """``pr_curves.png`` (precision vs recall per method, plain and boosted) and
    ``time_vs_auc.png`` (time per frame against AUC, the seed's trade-off plot)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 3.8), dpi=120)
    for (method, boost), (p, r) in curves.items():
        ax.plot(r, p, ls="-" if boost else "--",
                label=f"{method}{' + boost' if boost else ''}")
    ax.set(xlabel="recall", ylabel="precision", xlim=(0, 1), ylim=(0, 1.02),
           title="Recognition precision–recall")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(workdir, "pr_curves.png"))
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 3.8), dpi=120)
    for r in rows:
        ax.scatter(r["total_s"], r["auc"], marker="o" if r["boost"] else "x")
        ax.annotate(f"{r['method']}{' + boost' if r['boost'] else ''}",
                    (r["total_s"], r["auc"]), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    ax.set(xlabel="seconds per frame", ylabel="AUC", title="Time vs AUC")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(workdir, "time_vs_auc.png"))
    plt.close(fig)
