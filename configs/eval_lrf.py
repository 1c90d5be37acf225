"""LRF repeatability: Compass vs FLARE, SHOT's LRF, TOLDI, 3DSmoothNet's and GFrames (thesis 3.2,
Fig. 3.4).

    python -m experiments.evaluate --config=eval_lrf [--workdir=runs/eval_lrf]
    python -m experiments.evaluate --config=eval_lrf:stanford \\
        --config.data.root=../shared/data/stanford/bunny/data        # Stanford Views
    python -m experiments.evaluate --config=eval_lrf --config.adapt_steps=200   # adapt first

Writes lrf_results.csv / lrf_results.md (Rep with ρ = 0.97 on x̂ and ẑ, mean angle between
corresponding frames) and, for the first ``plot_pairs`` pairs of each scene, a PNG per method
colouring the keypoints repeatable / not. Arguments: '' (3DMatch layout, 1000 keypoints per
scan), 'stanford' (bunny scale: 1 mm voxel, 1.5 cm support), 'tiny' (tests). What it
measures: how often a method gives corresponding keypoints of two scans the same frame, up to
the scans' motion (docs/results.md has the published tables). Adaptation, declared in the
tables, never reads the scans' ground truth.
"""
from configs import eval_common


def get_config(arg=None):
    c = eval_common.base("" if arg == "stanford" else arg)
    c.task = "lrf"
    c.methods = "flare,shot,toldi,3dsn,gframes,compass"
    c.rho = 0.97
    c.match_dist = c.data.voxel          # a keypoint of i corresponds to j's point this close
    c.data.n_keypoints = 1000
    c.plot_pairs = 2
    c.adapt_steps = 0                    # > 0: test-time adaptation of compass/sound first
    c.data.min_overlap = 0.10            # Stanford pairs kept above this overlap
    if arg == "stanford":
        c.size = "stanford"
        c.data.update(voxel=0.001, radius=0.015)
        c.match_dist = 0.001
    elif c.size == "tiny":
        c.data.n_keypoints = 100
        c.plot_pairs = 1
    return c
