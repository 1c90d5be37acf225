"""One grammar for every method: names and keys resolve to the same record, the lists the
library and the CLI use derive from it, and a wrong name is refused with the choices."""
import pytest

from sphere_jax import checks
from sphere_jax.features import methods, registry


@pytest.mark.parametrize("spelling, key", [
    ("lead@compass", "lead_compass"), ("lead_compass", "lead_compass"),
    ("lead@flare", "lead"), ("lead", "lead"), ("LEAD@Compass", "lead_compass"),
    ("shot@shot", "shot"), ("lead@compass+vote", "lead_vote"), ("shot@shot+vote", "shot_vote"),
    ("lead@gt", "lead_gt"), ("lead_pn@flare", "lead_pn")])
def test_names_and_keys_spell_one_method(spelling, key):
    assert registry.resolve(spelling).key == key


def test_every_key_and_name_is_unique():
    names = [m.name for m in registry.METHODS]
    keys = [m.key for m in registry.METHODS]
    assert len(set(names)) == len(names) and len(set(keys)) == len(keys)


def test_library_lists_derive_from_the_registry():
    learned = registry.keys("descriptor", learned=True)
    hand_crafted = registry.keys("descriptor", learned=False)
    assert set(learned + hand_crafted) == set(registry.keys("descriptor"))
    assert learned == ("lead", "lead_compass", "lead_lrfnet", "lead_pn", "sound", "lead_modes")
    assert registry.keys("voted") == ("lead_vote", "shot_vote")
    assert registry.needs("lead_compass") == ("lead", "compass")
    assert registry.needs("compass") == ("compass",)                # an LRF's bundle
    assert all(m.build is not None for m in registry.METHODS)


@pytest.mark.parametrize("name, kinds", [("lead@shot", ("descriptor",)),
                                         ("lead_vote", ("descriptor",)),   # a procedure
                                         ("lead@gt", ("descriptor", "voted"))])
def test_a_name_outside_the_allowed_kinds_is_refused(name, kinds):
    with pytest.raises(checks.InputError, match="method must be one of"):
        registry.resolve(name, kinds)


def test_descriptor_factory_takes_the_grammar_name():
    assert methods.descriptor("usc@shot", 0.3) is not None
    with pytest.raises(checks.InputError, match="name must be one of"):
        methods.descriptor("lead_vote", 0.3)
