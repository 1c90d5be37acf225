"""Real-time pose pipeline (thesis ch. 7, Tables 7.5–7.6): box → crop → classify → choose
among stored views → FPFH → RANSAC or FGR → point-to-plane ICP.

    python -m experiments.evaluate --config=eval_pose [--workdir=runs/eval_pose]

On the embedded labelled RGB-D frames: stored views of every instance from the first two
views of each scene; every instance of the other views is posed from its ground-truth box,
classified by colour (logistic regression on HSV histograms of the stored views). Writes
pose.csv / pose.md: model accuracy, success (ADD-S under 10 % of the object's size), ADD-S,
median rotation error, ICP fitness (inlier ratio) and RMSE, seconds per stage and frames per
second, for RANSAC and FGR. Expected: most objects posed; FGR faster than RANSAC. Symmetric
objects (balls, cans, cones) make the rotation error meaningless, hence ADD-S.
"""
from configs import eval_common


def get_config(arg=None):
    c = eval_common.base(arg)
    c.task = "pose"
    c.methods = "ransac,fgr"
    c.data.voxel = 0.005              # FPFH / ICP resolution (m): objects of 12–28 cm
    c.data.max_frames = 0
    c.model_views = 2
    c.use_mask = False                # True: crop with the instance mask, not just the box
    if c.size == "tiny":
        c.data.max_frames = 2
        c.methods = "ransac"
    return c
