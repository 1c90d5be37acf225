"""Colour + shape object recognition on RGB-D crops (thesis ch. 6, Washington RGB-D protocols).

    python -m experiments.evaluate --config=eval_objects [--workdir=runs/eval_objects]
    python -m experiments.evaluate --config=eval_objects --config.data.root=/data/rgbd-dataset

Colour (HSV histogram), shape (the LEAD bundle applied to the whole object, seed 6.2) and
both, standard-scaled, with six scikit-learn classifiers, under the category
(leave-one-instance-out) and instance (leave-sequence-out, alternating contiguous frames)
protocols. Writes objects.csv (protocol, features, classifier, accuracy) and objects.md.
Expected on the embedded synthetic crops (10 categories × 3 instances): colour+shape at or
above the better of the two alone for most classifiers.
"""
from configs import eval_common


def get_config(arg=None):
    c = eval_common.base(arg)
    c.task = "objects"
    c.data.categories = ""            # comma-separated subset; empty: all
    c.bundle = c.bundles.lead         # shape feature; '' for colour only
    c.protocols = "category,instance_lso,instance_acf"
    c.classifiers = "RF,SVC,GNB,MLP,LR,kSVC"
    c.trials = 3                      # category protocol: random held-out instances
    c.block = 2                       # alternating contiguous frames: block length
    if c.size == "tiny":
        c.data.categories = "ball,can,cone,ring"
        c.classifiers = "GNB,LR"
        c.trials = 1
    return c
