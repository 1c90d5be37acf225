"""The benchmark suites of ``python -m experiments.bench --suite=NAME``, one module each with
``run(**flags) -> list of records`` (dicts of one row each)."""

SUITES = ("layers", "patches", "models", "registration", "train", "peers", "describe", "stages",
          "keypoints")
