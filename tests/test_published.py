"""Every published figure regenerates from the committed records (docs/records): the
repository's generated documents equal what ``experiments.publish`` renders from them, and a
hand edit of any of them is caught."""
import os
import re

import pytest

from experiments import publish, records


@pytest.fixture(scope="module")
def rendered():
    return publish.render()


def test_every_generated_document_equals_its_records(rendered):
    stale = [os.path.relpath(p, records.REPO) for p in publish.differences(rendered)]
    assert not stale, f"run python -m experiments.publish: {stale}"


def _generated(rendered, kind):
    """One generated file of each kind: results, README, a card, a bundle's evaluations."""
    pick = {"results": lambda p: p.endswith(os.path.join("docs", "results.md")),
            "readme": lambda p: p == os.path.join(records.REPO, "README.md"),
            "card": lambda p: p.endswith("MODEL_CARD.md") and "## Evaluations" in rendered[p],
            "evaluations": lambda p: p.endswith("evaluations.json") and rendered[p] != "{}\n",
            "index": lambda p: p.endswith(os.path.join("weights", "README.md"))}[kind]
    return next(p for p in rendered if pick(p))


def _hand_edited(text, path) -> str:
    """``text`` with the first digit of its first table changed (a number in a table line of
    markdown; in ``evaluations.json``, in the first table it stores)."""
    if path.endswith(".json"):
        at = text.index('"table"')
    else:
        at = next(m for m in re.finditer(r"^\|.*\d.*$", text, re.M)).start()
    digit = next(i for i in range(at, len(text)) if text[i].isdigit())
    return text[:digit] + ("1" if text[digit] != "1" else "2") + text[digit + 1:]


@pytest.mark.parametrize("kind", ["results", "readme", "card", "evaluations", "index"])
def test_a_hand_edit_of_a_generated_table_is_caught(rendered, kind, tmp_path):
    path = _generated(rendered, kind)
    edited = tmp_path / "edited"
    edited.write_text(_hand_edited(rendered[path], path))
    assert publish.differences({str(edited): rendered[path]}) == [str(edited)]
    assert publish.differences({path: rendered[path]}) == []


def test_every_record_is_published_and_every_section_has_its_record():
    index = records.read_index()
    kept = {n for n in os.listdir(records.ROOT) if os.path.isdir(os.path.join(records.ROOT, n))}
    assert kept == set(index["sections"]) | set(index["registered"]) | set(index["bench"])
    for name in kept:
        files = os.listdir(os.path.join(records.ROOT, name))
        assert all(f.endswith(records.KEPT) for f in files), (name, files)
