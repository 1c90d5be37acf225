"""Adaptation's rules that need no training: which kinds adapt, when it stops early."""
import numpy as np
import pytest

from sphere_jax import checks, training
from sphere_jax.training import adaptation, loop


def test_every_kind_trained_without_labels_adapts():
    kinds = adaptation.adaptable_kinds()
    assert {"compass", "lead", "lead_pn", "sound"} <= set(kinds) and "classify" not in kinds


def test_a_plateau_is_patience_evaluations_without_a_better_loss():
    plateau = loop.Plateau(2)
    seen = [plateau.reached(v) for v in (1.0, 0.9, 0.95, 0.9, 0.8, 0.85, 0.81)]
    assert seen == [False, False, False, True, False, False, True]
    never = loop.Plateau(0)
    assert not any(never.reached(v) for v in (1.0, 2.0, 3.0, 4.0))


def test_a_relative_plateau_waits_as_long_as_the_best_took():
    # best at the 5th evaluation (4 before it): patience 2 alone stops 2 later, relative 1
    # only after 4 without a better loss
    losses = (1.0, 0.9, 0.8, 0.7, 0.6, 0.65, 0.7, 0.62, 0.61, 0.9)
    fixed, relative = loop.Plateau(2), loop.Plateau(2, relative=1.0)
    assert [fixed.reached(v) for v in losses].index(True) == 6
    assert [relative.reached(v) for v in losses].index(True) == 8
    early = loop.Plateau(2, relative=1.0)          # a best at the start: patience decides
    assert [early.reached(v) for v in (1.0, 1.1, 1.2)] == [False, False, True]


def test_a_plateau_waits_out_its_grace():
    """A fine-tune whose first evaluations are worse than its start is not stopped before
    ``grace`` evaluations (the start, then the fresh optimiser's first losses)."""
    losses = (1.0, 1.3, 1.2, 1.1, 0.9, 0.8)
    plain = loop.Plateau(2)
    assert [plain.reached(v) for v in losses].index(True) == 2
    graced = loop.Plateau(2, grace=4)
    assert [graced.reached(v) for v in losses] == [False] * 6 and graced.best == 0.8
    late = loop.Plateau(2, grace=4)          # after the grace, patience decides as before
    assert [late.reached(v) for v in (1.0, 1.3, 1.2, 1.1, 1.2)] == [False] * 4 + [True]


def test_a_plateau_keeps_the_weights_of_its_best_evaluation():
    plateau = loop.Plateau(3)
    for step, v in enumerate((1.0, 0.7, 0.9, 0.8)):
        plateau.reached(v, {"params": {"w": np.full(2, step)}, "batch_stats": {}}, step)
    assert plateau.best_step == 1 and plateau.best == 0.7
    np.testing.assert_array_equal(plateau.best_state["params"]["w"], [1, 1])
    assert loop.Plateau(0).best_state is None


def test_adaptation_needs_a_budget_and_refuses_labelled_bundles():
    class Bundle:
        kind = "classify"
    with pytest.raises(checks.ConfigError, match="trained with labels"):
        training.adapt(Bundle(), "scans", 10, "w")
    Bundle.kind = "lead"
    with pytest.raises(checks.ConfigError, match="steps or minutes"):
        training.adapt(Bundle(), "scans", None, "w")
