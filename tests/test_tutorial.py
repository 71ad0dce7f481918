"""docs/tutorial.ipynb runs from top to bottom (load, run, plot, animate, sweep).

It is executed by nbclient in a temporary copy of the folders it reads (docs/,
examples/), so that its files (generated/, four_bar.html) land there, not in the
source tree. The four-bar's compiled module, already built for the session, is copied
into the copy's generated/ folder: the build cache is keyed by content, so the
notebook loads it instead of compiling again.
"""
import os
import shutil
from pathlib import Path

import pytest

from conftest import EXAMPLES, ROOT

nbclient = pytest.importorskip(
    "nbclient", reason="the tutorial test needs nbclient and ipykernel "
    "(pip install 'fccgen[test]')")
nbformat = pytest.importorskip("nbformat", reason="the tutorial test needs nbformat")
pytest.importorskip("ipykernel", reason="the tutorial test needs ipykernel")

CELL_TIMEOUT = 120          # seconds per cell: a generous bound for a loaded machine


def test_tutorial_notebook_runs(tmp_path, compiled, build_dir, monkeypatch):
    compiled("four_bar")                                 # built once per session
    work = tmp_path / "tree"
    shutil.copytree(ROOT / "docs", work / "docs",
                    ignore=shutil.ignore_patterns("figures", "performance", "accuracy"))
    shutil.copytree(EXAMPLES, work / "examples")
    shutil.copytree(build_dir / "four_bar", work / "docs" / "generated" / "four_bar")
    import fccgen
    source = str(Path(fccgen.__file__).resolve().parent.parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [source, *filter(None, [os.environ.get("PYTHONPATH")])]))
    monkeypatch.setenv("MPLBACKEND", "agg")
    nb = nbformat.read(work / "docs" / "tutorial.ipynb", as_version=4)
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT, kernel_name="python3",
                                     resources={"metadata": {"path": str(work / "docs")}})
    client.execute()
    text = "\n".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                     for o in c.get("outputs", []))
    assert "DOF 1 (decided)" in text               # the solver summary, after the run
    assert "2 runs, 0 failed" in text                    # the sweep
    page = work / "docs" / "four_bar.html"
    assert page.stat().st_size > 1_000_000               # plotly.js is inlined (~3 MB)
    assert not (ROOT / "docs" / "four_bar.html").exists()
