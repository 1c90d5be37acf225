"""The run record of an evaluation names the bundles its methods used, which the published
tables are stamped with."""
import warnings

import pytest

from configs import eval_classification, eval_registration
from sphere_jax import paths
from sphere_jax.eval import tasks
from sphere_jax.models import shipped


def test_run_record_names_the_bundles_the_methods_use():
    c = eval_registration.get_config("quick")
    c.methods = "fpfh,lead_compass"
    used = tasks.bundles_used(c)
    assert sorted(used) == ["compass", "lead"]
    assert used["lead"]["path"] == paths.relative(shipped.bundle_path("lead"))
    assert used["lead"]["steps_done"] > 0 and len(used["lead"]["fingerprint"]) == 16
    c = eval_classification.get_config("small")           # the whole-shape Compass
    assert sorted(tasks.bundles_used(c)) == ["compass_shapes"]
    c.methods = "pointnet"
    assert tasks.bundles_used(c) == {}


def test_a_bundle_set_for_a_kind_no_method_uses_is_named_in_a_warning():
    c = eval_registration.get_config("quick")
    c.methods = "shot,usc"
    c.bundles.lead = shipped.bundle_path("lead_pn")         # a slip: lead_pn meant
    with pytest.warns(UserWarning, match=r"config.bundles.lead=.* is not used: none of the "
                                         r"methods shot, usc needs a lead bundle"):
        tasks.check_bundles(c, ["shot", "usc"])
    c.methods = "shot,lead_pn"
    c.bundles.lead = shipped.bundle_path("lead")            # the defaults: no word
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tasks.check_bundles(c, ["shot", "lead_pn"])


def test_a_classification_that_finds_its_classifiers_counts_as_resumed(tmp_path):
    from sphere_jax.eval import classification
    c = eval_classification.get_config("small")
    assert classification.kept(tmp_path, c) == 0
    (tmp_path / "compass_pointnet").mkdir()              # a trained or interrupted classifier
    assert classification.kept(tmp_path, c) == 1
