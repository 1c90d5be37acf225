"""The keypoints suite's records: both registrations of a pair scored against the ground
truth, and the progressive outcome the threshold decides."""
from experiments.benchmarks import keypoints
from sphere_jax import align
from sphere_jax.data import demo


def test_a_pair_record_scores_both_ways_and_follows_the_threshold(monkeypatch):
    (src, dst), t_gt = demo.fragment_pair()
    monkeypatch.setattr(align, "CONFIDENT_INLIERS", 10)
    rec = keypoints.pair_record("fpfh", src, dst, t_gt, 4000)
    assert rec["whole"]["ok"] and rec["whole"]["right"] and rec["half"]["inliers"] > 0
    stop = rec["half"]["ok"] and rec["half"]["inliers"] >= 10
    assert rec["progressive"]["stopped_at_half"] == stop
    assert rec["progressive"]["right"] == rec["half" if stop else "whole"]["right"]
    rows = [{"pair": [0, 1], **rec}, {"pair": [0, 2], **rec}]
    row = keypoints.summary("fpfh", "3DMatch", rows, 4000)
    assert row["pairs"] == 2 and row["right_4000"] == 2
    assert row["right_progressive"] == 2 * rec["progressive"]["right"]
    assert row["seconds_progressive"] == round(2 * rec["progressive"]["seconds"], 1)
