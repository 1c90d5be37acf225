"""The describe benchmark's records: the keys the speed issue asks for, a hand-crafted method
with no network flops, and the learned pair's flops from XLA's cost analysis."""
import numpy as np

from experiments.benchmarks import describe

KEYS = {"method", "ms_per_keypoint", "gflop_per_keypoint", "gflop_per_s", "peak_fraction",
        "peak_rss_gb", "register_s"}


def test_records_of_a_hand_crafted_method():
    (rec,) = describe.run(keypoints=200, only="fpfh")
    assert KEYS <= set(rec) and rec["method"] == "fpfh"
    assert rec["gflop_per_keypoint"] is None and rec["peak_fraction"] is None
    assert rec["ms_per_keypoint"] > 0 and rec["peak_rss_gb"] > 0.1
    assert rec["register_stages"]["load"] >= 0 and rec["register_s"] > 0


def test_learned_flops_add_the_frame_and_the_descriptor():
    patches = (np.random.default_rng(0).normal(size=(8, 1225, 3)) * 0.4).astype(np.float32)
    lead, pair = describe._flops("lead", patches), describe._flops("lead_compass", patches)
    assert lead > 0.01 and pair > lead               # Compass's frame costs flops of its own
