"""Evaluations (numpy / open3d / scikit-learn side; models enter through inference bundles).

* hand-crafted baselines on exact neighbourhoods: :mod:`neighbourhood`, :mod:`lrfs` (SHOT,
  TOLDI), :mod:`descriptors` (SHOT, Spin Images, FPFH);
* registration and LRF benchmarks: :mod:`scenes` (inputs, rotated variant), :mod:`methods`
  (names → callables), :mod:`registration`, :mod:`repeatability`, :mod:`benchmark` (config →
  files), :mod:`report` (CSV, markdown, plots);
* recognition: :mod:`classification` (Compass + PointNet, NR/AR), :mod:`recognition` and
  :mod:`saliency` (Saliency Boost), :mod:`objects` (colour + shape), :mod:`pose`.
"""
