"""The benchmarks (numpy / open3d / scikit-learn side). The methods they compare come from
:mod:`sphere_jax.features` by name, the registration algorithm from
:mod:`sphere_jax.registration`; models enter through inference bundles.

* shared pieces: :mod:`scenes` (scan pairs with ground truth, preparation, the rotated
  variant, the scans of a config), :mod:`report` (tables, CSV, plots), :mod:`labelled`
  (labelled RGB-D frames, model views), :mod:`resume` and :mod:`processes` (interrupted and
  multi-process runs);
* the tasks, found by ``config.task`` through :mod:`tasks`, each with ``run(config, workdir,
  progress)``: :mod:`registration`, :mod:`repeatability` (LRFs), :mod:`classification`
  (Compass + PointNet, NR/AR), :mod:`recognition` (with :mod:`saliency`: Saliency Boost),
  :mod:`objects` (colour + shape), :mod:`pose`.
"""
