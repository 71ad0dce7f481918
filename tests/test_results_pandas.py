"""Results where people analyse them: docs/results.md's pandas and xarray lines run
as written on files fccgen wrote, and give the user's columns indexed by t."""
from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import ROOT

DOC = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def saved(compiled, tmp_path_factory):
    folder = tmp_path_factory.mktemp("pandas")
    result = compiled("double_pendulum").simulate(t_end=0.2, output_dt=0.01)
    for suffix in (".h5", ".csv"):
        result.save(folder / f"double_pendulum{suffix}")
    return folder, result


def doc_block(word: str) -> str:
    (block,) = [b for b in re.findall(r"```python\n(.*?)```", DOC, flags=re.S) if word in b]
    return block


@pytest.mark.parametrize("word", ["to_pandas", "xarray"])
def test_the_documented_lines_read_the_files(saved, monkeypatch, word):
    folder, result = saved
    if word == "xarray":
        pytest.importorskip("xarray")
        pytest.importorskip("h5netcdf")
    monkeypatch.chdir(folder)
    scope: dict = {}
    exec(doc_block(word), scope)                 # the docs' lines, as written
    frame = scope["frame"]
    assert frame.index.name == "t" and len(frame) == 21
    assert list(frame.columns) == result.names[1:]
    assert np.array_equal(frame["P2.x"].to_numpy(), result["P2.x"])
    assert np.array_equal(frame.index.to_numpy(), result.t)


def test_read_csv_with_t_as_index(saved):
    import pandas as pd
    folder, result = saved
    frame = pd.read_csv(folder / "double_pendulum.csv", index_col="t")
    assert list(frame.columns) == result.names[1:]
    assert np.array_equal(frame["energy"].to_numpy(), result["energy"])
