"""Registration benchmark: learned vs hand-crafted descriptors (thesis 4.3, Tables 4.1–4.4).

    python -m experiments.evaluate --config=eval_registration [--workdir=runs/eval_registration]
    python -m experiments.evaluate --config=eval_registration --config.rotate=True   # rotated
    python -m experiments.evaluate --config=eval_registration \\
        --config.data.root=/data/3dmatch/fragments --config.methods=fpfh,shot,lead,sound

Writes results.csv / results.md (rows = methods, columns = scenes + mean: FMR, inlier ratio,
correct matches, registration recall, RRE, RTE, ms per keypoint) and fmr_vs_tau2.png.
Arguments: '' (5000 keypoints, every pair), 'quick' (2500 keypoints, 8 pairs per scene: the
README's main job, with the shipped LEAD and LEAD-PN), 'tiny' (tests). What it measures: how
well each descriptor's mutual nearest neighbours match corresponding points of overlapping
scans, and whether RANSAC registers them; the published tables are in docs/results.md.
``lead_vote`` and ``shot_vote`` add the pair vote (``sphere_jax.registration.vote``: a first
pass in the methods' own LRFs votes the pair's rotation, the second describes both scans in it);
``lead_gt`` and ``shot_gt`` the ground-truth-frame diagnostics (upper bounds, not methods).
"""
from configs import eval_common


def get_config(arg=None):
    c = eval_common.base(arg)
    c.task = "registration"
    c.methods = "fpfh,shot,spin,usc,lead,lead_compass,lead_pn,sound"
    c.fpfh_radius = 0.15              # FPFH's own neighbourhood (its support reaches 2x this)
    c.tau1, c.tau2 = 0.10, 0.05
    c.ransac_distance = 0.05
    c.ransac_iterations = 50_000
    c.vote_hypotheses = 5             # modes of a pair's vote that RANSAC's consensus chooses from
    c.vote_box = True                 # ... and the box turns of the strongest (vote.box_orbit)
    c.tau2_curve = [0.0, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1, 0.15, 0.2]
    if c.size == "quick":
        c.methods = "fpfh,shot,lead,lead_pn"
    elif c.size == "tiny":
        c.methods = "fpfh,shot"
        c.ransac_iterations = 2000
    return c
