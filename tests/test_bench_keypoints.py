"""The keypoints suite's records: every share's registration of a pair scored against the
ground truth, and the progressive outcome the threshold decides."""
from experiments.benchmarks import keypoints
from sphere_jax.data import demo
from sphere_jax.registration import pipeline


def test_a_pair_record_scores_every_share_and_follows_the_threshold(monkeypatch):
    (src, dst), t_gt = demo.fragment_pair()
    monkeypatch.setattr(pipeline, "CONFIDENT_INLIERS", 10)
    assert keypoints.shares(4000) == [1000, 2000, 4000]
    rec = keypoints.pair_record("fpfh", src, dst, t_gt, 4000)
    assert rec["4000"]["ok"] and rec["4000"]["right"] and rec["1000"]["inliers"] > 0
    assert rec["4000"]["matches"] >= rec["4000"]["inliers"] and rec["4000"]["fitness"] > 0.05
    stop = next(k for k in (1000, 2000, 4000)
                if k == 4000 or rec[str(k)]["confident"])
    assert all(rec[str(k)]["inliers"] >= 10 for k in (1000, 2000, 4000) if rec[str(k)]["confident"])
    assert rec["progressive"]["stopped_at"] == stop
    assert rec["progressive"]["right"] == rec[str(stop)]["right"]
    assert rec["progressive"]["seconds"] >= rec[str(stop)]["seconds"]
    rows = [{"pair": [0, 1], **rec}, {"pair": [0, 2], **rec}]
    row = keypoints.summary("fpfh", "3DMatch", rows, 4000)
    assert row["pairs"] == 2 and row["right_4000"] == 2
    assert row["right_progressive"] == 2 * rec["progressive"]["right"]
    assert f"{stop}: 2" in row["stopped_at"]
    assert row["seconds_progressive"] == round(2 * rec["progressive"]["seconds"], 1)
