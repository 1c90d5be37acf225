"""Colour + shape object recognition on RGB-D crops (seed ch. 6), with scikit-learn.

Per crop: a colour feature (pluggable: any ``f(rgb [H, W, 3] uint8, mask [H, W]) -> [D]``, e.g.
a pretrained CNN the user supplies; default a joint HSV histogram) and a global shape feature
(the learned descriptor of the whole object, seed 6.2: one patch centred on the object with the
radius of half its largest bounding-box side). Features are standard-scaled on the training
split and fed to six classifiers. Protocols of the Washington RGB-D Object benchmark:

* ``category``: leave one instance of every category out (``trials`` random draws);
* ``instance_lso``: leave-sequence-out — train on videos 1 and 4, test on video 2;
* ``instance_acf``: alternating contiguous frames — each video cut into blocks of ``block``
  consecutive frames, alternately train and test.
"""
from __future__ import annotations

import warnings
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from sphere_jax.bundles import inference
from sphere_jax.data.generators import synthetic
from sphere_jax.data.readers import washington
from sphere_jax.data.readers.washington import Sample
from sphere_jax.eval import report, tasks

PROTOCOLS = ("category", "instance_lso", "instance_acf")
FEATURE_SETS = ("colour", "shape", "colour+shape")


def classifiers(seed=0):
    """The six classifiers, each behind a StandardScaler fitted on the training split."""
    from sklearn.ensemble import RandomForestClassifier
    from sklearn.linear_model import LogisticRegression
    from sklearn.naive_bayes import GaussianNB
    from sklearn.neural_network import MLPClassifier
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC
    models = {"RF": RandomForestClassifier(200, random_state=seed),
              "SVC": SVC(kernel="linear"),
              "GNB": GaussianNB(),
              "MLP": MLPClassifier((256,), max_iter=1000, random_state=seed),
              "LR": LogisticRegression(max_iter=5000),
              "kSVC": SVC(kernel="rbf")}
    return {k: make_pipeline(StandardScaler(), m) for k, m in models.items()}


def hsv_histogram(rgb, mask, bins=(8, 4, 4)):
    """Joint HSV histogram of the masked pixels, L1-normalised (a classical colour feature)."""
    import matplotlib.colors
    hsv = matplotlib.colors.rgb_to_hsv(np.asarray(rgb, np.float64)[..., :3] / 255.0)
    px = hsv[np.asarray(mask, bool)]
    if len(px) == 0:
        return np.zeros(int(np.prod(bins)), np.float32)
    hist, _ = np.histogramdd(px, bins=bins, range=[(0, 1)] * 3)
    return (hist.reshape(-1) / len(px)).astype(np.float32)


def shape_feature(bundle, chunk=1):
    """``f(points [N, 3]) -> [D]``: a descriptor bundle (LEAD, LEAD-PN, SOUND) applied to
    the whole object as one patch."""
    def describe(points):
        lo, hi = points.min(0), points.max(0)
        centre = (lo + hi) / 2
        radius = max(float(np.max(hi - lo)) / 2, 1e-3)
        return bundle.describe(points, centre[None], radius=radius, chunk=chunk)[0]
    return describe


def features(samples: list[Sample], colour: Callable = hsv_histogram,
             shape: Callable | None = None, progress=True):
    """``{feature set: [n, D]}`` for the crops; ``colour+shape`` is the concatenation."""
    cols, shapes_ = [], []
    for s in tqdm(samples, desc="features", disable=not progress):
        mask = s.mask()
        cols.append(np.asarray(colour(s.color(), mask), np.float32))
        if shape is not None:
            shapes_.append(np.asarray(shape(s.points(mask)), np.float32))
    out = {"colour": np.stack(cols)}
    if shape is not None:
        out["shape"] = np.stack(shapes_)
        out["colour+shape"] = np.concatenate([out["colour"], out["shape"]], 1)
    return out


def splits(samples: list[Sample], protocol, trials=3, block=2, seed=0):
    """``[(train_idx, test_idx, labels)]`` for a protocol (labels: category or instance)."""
    cat = np.array([s.category for s in samples])
    inst = np.array([s.instance for s in samples])
    video = np.array([s.video for s in samples])
    if protocol == "category":
        rng = np.random.default_rng(seed)
        out = []
        for _ in range(trials):
            held = {c: rng.choice(sorted(set(inst[cat == c]))) for c in sorted(set(cat))}
            test = np.array([inst[k] == held[cat[k]] for k in range(len(samples))])
            out.append((np.nonzero(~test)[0], np.nonzero(test)[0], cat))
        return out
    if protocol == "instance_lso":
        test = video == 2
        return [(np.nonzero(~test)[0], np.nonzero(test)[0], inst)]
    if protocol == "instance_acf":
        test = np.zeros(len(samples), bool)
        for key in sorted(set(zip(inst, video))):
            rows = [k for k in range(len(samples)) if (inst[k], video[k]) == key]
            rows.sort(key=lambda k: samples[k].frame)
            for pos, k in enumerate(rows):
                test[k] = (pos // block) % 2 == 1
        return [(np.nonzero(~test)[0], np.nonzero(test)[0], inst)]
    raise ValueError(f"protocol must be one of {PROTOCOLS}, got {protocol!r}")


def evaluate(samples, feats: dict, protocols=PROTOCOLS, classifier_names=None, trials=3,
             block=2, seed=0, progress=True):
    """Rows ``{protocol, features, classifier, accuracy}`` (mean over trials)."""
    from sklearn.base import clone
    models = classifiers(seed)
    names = classifier_names or list(models)
    rows = []
    jobs = [(p, f, c) for p in protocols for f in feats for c in names]
    for protocol, fset, name in tqdm(jobs, desc="classifiers", disable=not progress):
        accs = []
        for train, test, labels in splits(samples, protocol, trials, block, seed):
            if len(test) == 0 or len(set(labels[train])) < 2:
                raise ValueError(f"protocol {protocol!r} leaves an empty split on this data")
            model = clone(models[name]).fit(feats[fset][train], labels[train])
            accs.append(float(np.mean(model.predict(feats[fset][test]) == labels[test])))
        rows.append({"protocol": protocol, "features": fset, "classifier": name,
                     "accuracy": float(np.mean(accs))})
    return rows


def markdown(rows):
    """One table per protocol: rows = classifiers, columns = feature sets."""
    parts = []
    for protocol in dict.fromkeys(r["protocol"] for r in rows):
        mine = [r for r in rows if r["protocol"] == protocol]
        parts += [f"**{protocol}** (accuracy)", "",
                  report.pivot_table(mine, "classifier", "features", "accuracy"), ""]
    return "\n".join(parts)


def run(config, workdir, progress=True):
    """The colour + shape benchmark of ``configs/eval_objects.py``: objects.csv / objects.md."""
    root = config.data.root or synthetic.default_root("washington", config.seed)
    cats = [c.strip() for c in config.data.categories.split(",") if c.strip()] or None
    samples = washington.read_dataset(root, cats)
    shape = shape_feature(inference.load_bundle(config.bundle)) if config.bundle else None
    if shape is None:
        warnings.warn("no descriptor bundle: colour features only", stacklevel=2)
    feats = features(samples, hsv_histogram, shape, progress)
    rows = evaluate(samples, feats, [p.strip() for p in config.protocols.split(",")],
                    [c.strip() for c in config.classifiers.split(",")], config.trials,
                    config.block, config.seed, progress)
    md = (f"# Colour + shape recognition ({len(samples)} crops, "
          f"{len({s.instance for s in samples})} instances)\n\n" + markdown(rows))
    report.write(workdir, "objects", rows, ("protocol", "features", "classifier", "accuracy"),
                 md)
    return rows, md


TASK = tasks.Task(run=run)
