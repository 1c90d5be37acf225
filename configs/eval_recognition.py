"""Local-descriptor recognition with Saliency Boost (thesis 2.2.3.1 and ch. 5, Tables 5.1–5.5).

    python -m experiments.evaluate --config=eval_recognition [--workdir=runs/eval_recognition]
    python -m experiments.evaluate --config=eval_recognition --config.methods=shot,fpfh,lead

A database of partial views from the first two views of every table-top scene; the other
views are searched, plain and with Saliency Boost (spectral-residual saliency, no downloaded
weights). Writes recognition.csv / recognition.md (AUC, keypoints and seconds per stage per
frame), pr_curves.png and time_vs_auc.png. Expected on the embedded frames: boosting cuts the
scene keypoints and the time per frame by 2–3x; how much AUC it costs or gains depends on the
descriptor.
"""
from configs import eval_common


def get_config(arg=None):
    c = eval_common.base(arg)
    c.task = "recognition"
    c.methods = "shot,fpfh"
    c.data.update(voxel=0.005, radius=0.08)   # objects of 12–28 cm: 8 cm supports
    c.data.max_frames = 0                     # test frames kept (0: all)
    c.model_views = 2                         # views per scene that build the database
    c.leaf = 0.03                             # uniform keypoints every 3 cm ('iss' below)
    c.keypoints = "uniform"                   # or 'iss'
    c.max_depth = 1.6                         # metres; the table, not the far floor
    c.match_threshold = 0.3                   # descriptor distance (unit-length descriptors)
    c.gc_resolution = 0.01                    # geometric consistency (m)
    c.min_group = 3
    c.saliency_factor = 1.0                   # salient: above this × the mean saliency
    if c.size == "tiny":
        c.methods = "shot"
        c.data.max_frames = 4
    return c
