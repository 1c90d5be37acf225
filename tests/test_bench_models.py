"""The models benchmark runs every config's forward and, on the real fragment, describes with
and without the fused path (keypoints with too little support left out)."""
import pytest

from experiments.benchmarks import models as bench_models
from sphere_jax import paths


@pytest.mark.slow
def test_models_suite_times_forward_and_description():
    records = bench_models.run(sizes=("tiny",), repeats=1, keypoints=5000, only="lead")
    assert [r["config"] for r in records] == ["lead:tiny", "lead_pn:tiny"]
    assert all(r["fwd_ms"] > 0 for r in records)
    if paths.real_data("3dmatch", "7-scenes-redkitchen", "cloud_bin_0.ply"):
        lead = records[0]
        assert lead["describe_ms_per_kp"] > 0 and lead["unfused_ms_per_kp"] > 0
