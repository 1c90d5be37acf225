"""The describe benchmark's records: the keys the speed issue asks for, a hand-crafted method
with no network flops, and the learned pair's flops from XLA's cost analysis."""
import pytest
import numpy as np

from experiments.benchmarks import describe

KEYS = {"method", "ms_per_keypoint", "gflop_per_keypoint", "gflop_per_s", "peak_fraction",
        "peak_rss_gb", "register_s", "register_warm_s", "others_cpu"}


@pytest.mark.slow
def test_records_of_a_hand_crafted_method():
    (rec,) = describe.run(keypoints=200, only="fpfh")
    assert KEYS <= set(rec) and rec["method"] == "fpfh"
    assert rec["gflop_per_keypoint"] is None and rec["peak_fraction"] is None
    assert rec["ms_per_keypoint"] > 0 and rec["peak_rss_gb"] > 0.1
    assert rec["others_cpu"] is None or 0 <= rec["others_cpu"] <= 1
    assert rec["register_stages"]["load"] >= 0 and rec["register_s"] > 0
    assert rec["register_warm_s"] > 0
    # register describes a quarter of 200 keypoints first, then half, then all
    assert len(rec["register_described"]) == 2
    assert all(d in (50, 100, 200) for d in rec["register_described"])


@pytest.mark.slow
def test_learned_flops_add_the_frame_and_the_descriptor():
    patches = (np.random.default_rng(0).normal(size=(8, 1225, 3)) * 0.4).astype(np.float32)
    lead, pair = describe._flops("lead", patches), describe._flops("lead_compass", patches)
    assert lead > 0.01 and pair > lead               # Compass's frame costs flops of its own


def test_flops_count_every_block_of_the_fused_layers():
    # XLA counts a loop's body once: counted per block or per slice, the flops per patch would
    # fall as the chunk grows (8 patches: 4 blocks of LEAD's first layer, one slice; 64
    # patches: two slices of 32, 16 blocks each).
    rng = np.random.default_rng(1)
    small, large = ((rng.normal(size=(n, 1225, 3)) * 0.4).astype(np.float32) for n in (8, 64))
    per_patch = describe._flops("lead", small), describe._flops("lead", large)
    assert abs(per_patch[0] - per_patch[1]) < 0.01 * per_patch[1]
    assert per_patch[1] > 0.1     # the shipped LEAD: 0.123 GFLOP per patch (docs/performance.md)


def test_flops_of_a_jitted_vmap_count_the_whole_batch():
    # The stages benchmark counts jit(vmap(per-patch function)); unwrapping past the vmap
    # would count one patch, or fail on the unbatched shapes.
    import jax
    m = np.random.default_rng(2).normal(size=(16, 16)).astype(np.float32)
    x = np.ones((8, 16), np.float32)
    gflop = describe.unrolled_gflop(jax.jit(jax.vmap(lambda v: m @ v)), x)
    assert abs(gflop * 1e9 - 2 * 8 * 16 * 16) <= 8 * 16      # XLA may count the adds apart
