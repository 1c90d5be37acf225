"""What every public entry point checks before it calls anything else, and the errors it raises.

All errors of the project derive from :class:`SphereJaxError` (a ``ValueError``), so one
``except sphere_jax.SphereJaxError`` catches every refusal of bad input. A message names the
argument (or file and line), what was expected and what was received. The checks run before
any third-party call: scikit-learn, open3d or flax never see an array we have not looked at.
"""
from __future__ import annotations

import numbers

import numpy as np

ROTATION_TOL = 1e-3           # |FᵀF − I| and |det F − 1| allowed in given frames


class SphereJaxError(ValueError):
    """Base of every error the project raises for bad input, files, bundles or configs."""


class InputError(SphereJaxError):
    """An argument of a public function has the wrong type, shape or value."""

    def __init__(self, name, expected=None, got=None, verb="be"):
        # One argument: a ready message (libraries re-raise errors as type(e)(text)).
        super().__init__(name if expected is None else f"{name} must {verb} {expected}; got {got}")
        self.name = name


class DataError(SphereJaxError):
    """A data file is missing, truncated or malformed."""

    def __init__(self, path, what=None, line=None):
        where = f"{path}" + (f", line {line}" if line is not None else "")
        super().__init__(where if what is None else f"{where}: {what}")
        self.path, self.line = str(path), line


class MissingError(SphereJaxError, FileNotFoundError):
    """A file or folder the caller named does not exist or lacks what it must hold."""


class BundleError(SphereJaxError):
    """A bundle folder is missing, unreadable or does not fit its config."""

    def __init__(self, path, what=None):
        super().__init__(path if what is None else f"bundle {path}: {what}")
        self.path = str(path)


class ConfigError(SphereJaxError):
    """A config field has a value the run cannot use (checked before any work starts)."""

    def __init__(self, field, expected=None, got=None):
        super().__init__(field if expected is None else f"{field} must be {expected}; got {got!r}")
        self.field = field


def shown(x) -> str:
    """A short description of a received value for messages."""
    if isinstance(x, np.ndarray) or hasattr(x, "__array__") and not np.isscalar(x):
        a = np.asarray(x)
        return f"an array of shape {a.shape} and dtype {a.dtype}"
    text = repr(x)
    return f"{type(x).__name__} {text[:60]}" if not isinstance(x, (int, float)) else text


def _numeric_array(x, name, expected):
    try:
        a = np.asarray(x)
    except Exception:                     # ragged lists and the like
        raise InputError(name, expected, f"{type(x).__name__} that is not an array") from None
    if a.dtype.kind not in "iuf":
        raise InputError(name, expected, shown(a))
    return a


def cloud(points, name="points", dtype=np.float32) -> np.ndarray:
    """``points`` as a ``[N, 3]`` array of ``dtype`` (None: a float array keeps its precision,
    the hand-crafted baselines work in float64): non-empty, finite, real numbers. Also takes
    an open3d point cloud (legacy or tensor)."""
    points = _from_open3d(points)
    a = _numeric_array(points, name, "a float array [N, 3]")
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(name, "a float array [N, 3]", shown(a))
    if len(a) == 0:
        raise InputError(name, "a non-empty cloud [N, 3]", "0 points")
    bad = ~np.isfinite(a).all(1)
    if bad.any():
        raise InputError(name, "finite coordinates",
                         f"{int(bad.sum())} non-finite point(s), the first at row "
                         f"{int(np.argmax(bad))}")
    if dtype is None:
        return a if a.dtype.kind == "f" else a.astype(np.float64)
    return a.astype(dtype, copy=False)


def _from_open3d(points):
    kind = type(points).__module__ or ""
    if not kind.startswith("open3d"):
        return points
    if hasattr(points, "point"):                                   # open3d.t.geometry
        # An empty tensor cloud has no 'positions' attribute at all (open3d's KeyError).
        if "positions" not in points.point:
            return np.zeros((0, 3), np.float32)
        return points.point.positions.numpy()
    return np.asarray(points.points)


KEYPOINT_FORMS = "integer indices [K] into points or float coordinates [K, 3]"


def keypoints(kp, n_points, name="keypoints"):
    """``(indices [K] int64, None)`` or ``(None, coordinates [K, 3] float32)``; anything else
    (a boolean mask, float indices, one coordinate ``(3,)``, ``[K, 2]``...) is an error naming
    both accepted forms."""
    a = np.asarray(kp) if not isinstance(kp, np.ndarray) else kp
    if a.dtype == bool:
        raise InputError(name, KEYPOINT_FORMS,
                         f"a boolean mask of shape {a.shape} (pass np.flatnonzero(mask))")
    if a.ndim == 1 and a.size == 0:
        return np.zeros(0, np.int64), None
    if a.dtype.kind in "iu" and a.ndim == 1:
        if a.min() < 0 or a.max() >= n_points:
            raise InputError(name, f"indices in 0..{n_points - 1} (points has {n_points})",
                             f"indices from {a.min()} to {a.max()}")
        return a.astype(np.int64), None
    if a.dtype.kind == "f" and a.ndim == 2 and a.shape[1] == 3:
        bad = ~np.isfinite(a).all(1)
        if bad.any():
            raise InputError(name, "finite coordinates [K, 3]",
                             f"{int(bad.sum())} non-finite row(s), the first at row "
                             f"{int(np.argmax(bad))}")
        return None, a.astype(np.float32)
    raise InputError(name, KEYPOINT_FORMS, shown(a))


def positive(value, name, integer=False, default=None):
    """A positive finite number (``integer``: a positive int). ``None`` gives ``default``;
    anything given is checked, never replaced."""
    return _bounded(value, name, integer, default, "positive", lambda v: v > 0)


def non_negative(value, name, integer=False, default=None):
    """:func:`positive`, zero allowed."""
    return _bounded(value, name, integer, default, "non-negative", lambda v: v >= 0)


def fraction(value, name, default=None):
    """A number in [0, 1] (a share: ICP fitness, an overlap); ``None`` gives ``default``."""
    if value is None:
        return default
    number = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not number or not 0 <= value <= 1:                 # NaN fails the comparison too
        raise InputError(name, "a number in [0, 1]", repr(value) if number else shown(value))
    return float(value)


def _bounded(value, name, integer, default, word, ok):
    if value is None:
        return default
    ok_type = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, ok_type):
        raise InputError(name, f"a {word} " + ("integer" if integer else "number"),
                         shown(value))
    if not np.isfinite(value) or not ok(value):
        raise InputError(name, f"a {word} " + ("integer" if integer else "finite number"),
                         repr(value))
    return int(value) if integer else float(value)


def rotations(frames, count, name="frames", tol=ROTATION_TOL) -> np.ndarray:
    """``frames`` as float32 ``[count, 3, 3]`` rotations: finite, orthonormal and det +1
    within ``tol``."""
    a = _numeric_array(frames, name, f"rotations [{count}, 3, 3]")
    if a.shape != (count, 3, 3):
        raise InputError(name, f"rotations [{count}, 3, 3] (one per keypoint)", shown(a))
    a = a.astype(np.float64)
    bad = ~np.isfinite(a).all((1, 2))
    if bad.any():
        raise InputError(name, "finite rotations",
                         f"{int(bad.sum())} non-finite frame(s), the first at {np.argmax(bad)}")
    ortho = np.abs(np.einsum("kji,kjl->kil", a, a) - np.eye(3)).max((1, 2))
    det = np.linalg.det(a)
    bad = (ortho > tol) | (np.abs(det - 1) > tol)
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(name, f"rotations (FᵀF = I and det F = +1 within {tol})",
                         f"{int(bad.sum())} frame(s) that are not, the first at {k} "
                         f"(|FᵀF − I| = {ortho[k]:.3g}, det = {det[k]:.4g})")
    return a.astype(np.float32)


def flag(value, name) -> bool:
    """A bool (numpy's too): a string such as ``"no"`` would otherwise read as true."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(name, "True or False", shown(value))
    return bool(value)


def choice(value, name, options):
    if value not in options:
        raise InputError(name, "one of " + ", ".join(map(repr, options)), repr(value))
    return value


# ---- config values, checked before a run does any work -----------------------------------------

# field -> (kind, lower bound, whether the bound itself is allowed); checked where present.
CONFIG_RULES = {
    "train.steps": (int, 1, True), "train.batch_size": (int, 1, True),
    "train.learning_rate": (float, 0, False), "train.log_every": (int, 1, True),
    "train.warmup_steps": (int, 0, True), "train.final_lr_fraction": (float, 0, True),
    "train.eval_every": (int, 1, True), "train.checkpoint_every": (int, 1, True),
    "train.eval_batches": (int, 1, True), "train.keep_checkpoints": (int, 1, True),
    "train.time_budget_s": (float, 0, True), "train.early_stop_patience": (int, 0, True),
    "train.early_stop_relative": (float, 0, True), "train.early_stop_grace": (int, 0, True),
    "data.radius": (float, 0, False), "data.voxel": (float, 0, False),
    "data.keypoint_leaf": (float, 0, False), "data.n_points": (int, 1, True),
    "data.min_points": (int, 0, True), "data.n_keypoints": (int, 1, True),
    "data.normal_k": (int, 3, True), "data.max_pairs": (int, 0, True),
    "data.val_fraction": (float, 0, True), "data.copy_jitter": (float, 0, True),
    "infer_chunk": (int, 1, True), "seed": (int, 0, True),
    "chunk": (int, 1, True), "adapt_steps": (int, 0, True),
    # evaluation thresholds: a negative or NaN one scores every method 0 without a word
    "tau1": (float, 0, False), "tau2": (float, 0, False), "rho": (float, 0, False),
    "match_dist": (float, 0, False), "ransac_distance": (float, 0, False),
    "ransac_iterations": (int, 1, True), "evaluation.ransac_iterations": (int, 1, True),
    "fpfh_radius": (float, 0, False),
}
# field -> (upper bound, whether it is allowed), for the fields that have one
UPPER = {"data.val_fraction": (1, False), "tau2": (1, True), "rho": (1, True),
         "train.final_lr_fraction": (1, True)}
NOTES = {"data.max_pairs": " (0: every pair)"}


def config_values(config, prefix="config"):
    """Raise :class:`ConfigError` for the first field of :data:`CONFIG_RULES` that ``config``
    (an ml_collections config) holds with a value of the wrong type, non-finite or out of
    range; ``None`` passes (a placeholder meaning 'the default')."""
    for field, (kind, low, inclusive) in CONFIG_RULES.items():
        node, found = config, True
        for part in field.split("."):
            if not hasattr(node, "get") or part not in node:
                found = False
                break
            node = node[part]
        if not found or node is None:
            continue
        ok_type = numbers.Integral if kind is int else numbers.Real
        bound = (">= " if inclusive else "> ") + str(low)
        expected = f"{'an integer' if kind is int else 'a finite number'} {bound}"
        high, high_ok = UPPER.get(field, (np.inf, True))
        if high < np.inf:
            expected += f" and {'at most' if high_ok else 'below'} {high}"
        expected += NOTES.get(field, "")
        if isinstance(node, bool) or not isinstance(node, ok_type):
            raise ConfigError(f"{prefix}.{field}", expected, node)
        bad = not np.isfinite(node) or (node < low if inclusive else node <= low) \
            or (node > high if high_ok else node >= high)
        if bad:
            raise ConfigError(f"{prefix}.{field}", expected, node)
    return config
