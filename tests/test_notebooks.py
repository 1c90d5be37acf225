"""Every notebook runs top to bottom headless (nbclient), within a time budget."""
import glob
import os
import time

import pytest

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop

NOTEBOOKS = sorted(glob.glob(os.path.join(os.path.dirname(__file__), "..", "notebooks",
                                          "*.ipynb")))
BUDGET_S = 300                      # per notebook on the 2-core machine


@pytest.mark.parametrize("path", NOTEBOOKS, ids=os.path.basename)
def test_notebook_runs(path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("NOTEBOOK_TRAIN_STEPS", "100")   # the training demo, shortened
    monkeypatch.setenv("NOTEBOOK_ADAPT_MINUTES", "1")   # the adaptation demo, shortened
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    start = time.perf_counter()
    nbclient.NotebookClient(nb, timeout=BUDGET_S, kernel_name="python3",
                            resources={"metadata": {"path": os.path.dirname(path)}}).execute()
    elapsed = time.perf_counter() - start
    images = sum("image/png" in o.get("data", {}) for c in nb.cells for o in c.get("outputs", []))
    print(f"{os.path.basename(path)}: {elapsed:.0f} s, {images} figure(s)")
    assert images >= 1
    assert elapsed < BUDGET_S
    # What a notebook shows must mean the same on any machine: no absolute path of this one.
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    shown = [str(o) for c in nb.cells for o in c.get("outputs", [])]
    for root in (here, os.path.dirname(here), os.path.expanduser("~")):
        assert not any(root + os.sep in text for text in shown), root


def test_there_are_five_notebooks():
    assert len(NOTEBOOKS) == 5
