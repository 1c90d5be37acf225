"""Evaluations (numpy / open3d / scikit-learn side; models enter through inference bundles).

* hand-crafted baselines on exact neighbourhoods: :mod:`neighbourhood`, :mod:`lrfs` (SHOT,
  TOLDI), :mod:`descriptors` (SHOT, Spin Images, FPFH);
* shared pieces: :mod:`scenes` (scan pairs, preparation, the rotated variant, the scans of a
  config), :mod:`methods` (names → callables, bundle choice), :mod:`voting` (the pair vote:
  frames voted from a first pass of matches), :mod:`report` (tables, CSV,
  plots), :mod:`labelled` (labelled RGB-D frames, model views, Kabsch);
* the tasks, found by ``config.task`` through :mod:`tasks`, each with ``run(config, workdir,
  progress)``: :mod:`registration`, :mod:`repeatability` (LRFs), :mod:`classification`
  (Compass + PointNet, NR/AR), :mod:`recognition` (with :mod:`saliency`: Saliency Boost),
  :mod:`objects` (colour + shape), :mod:`pose`.
"""
