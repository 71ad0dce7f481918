"""Results say how they were made (docs/design.md §4): fccgen version, model hash,
method and settings, run statistics, warnings and events travel with the numbers into
CSV (a JSON sidecar), NPZ and HDF5, and come back with Result.load."""
from __future__ import annotations

import csv
import json
import sys

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.errors import HostError, ResultMetadataWarning
from fccgen.results.provenance import model_hash
from fccgen.results.files import sidecar_path
from fccgen.results.result import Result, check_output

DOUBLE = EXAMPLES / "double_pendulum.yaml"
EVENTS = [{"time": 0.25, "name": "latch1", "impulse": 0.5, "energy_before": 1.0,
           "energy_after": 0.75},
          {"time": 0.5, "name": "stop1", "impulse": 0.0, "energy_before": 0.75,
           "energy_after": 0.75}]


@pytest.fixture(scope="module")
def run(compiled):
    return compiled("double_pendulum").simulate(t_end=0.2, method="dopri5", rtol=1e-7)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".h5"])
def test_every_format_keeps_how_the_run_was_made(run, tmp_path, suffix):
    run.info["events"] = EVENTS                 # as a run with events records them
    back = Result.load(run.save(tmp_path / f"run{suffix}"))
    # exactly what the run recorded, as JSON keeps it (tuples become lists)
    assert back.info == json.loads(json.dumps(run.info))
    info = back.info
    assert info["fccgen_version"] == fccgen.__version__ and info["created"].endswith("+00:00")
    assert info["model"]["name"] == "double_pendulum"
    assert info["model"]["source"].endswith("double_pendulum.yaml")
    assert info["method"] == "dopri5" and info["options"] == {"rtol": 1e-7, "atol": 1e-9}
    assert info["t_end"] == 0.2 and info["steps"] > 0 and "warnings" in info
    assert set(info["solver"]) == {"rank_tol", "position_tol", "max_newton",
                                   "linear_solver", "path"}
    # 6 coordinates, well posed at the start (runtime/paths.py): auto takes the sparse path
    assert info["solver"]["path"] == "sparse"
    assert info["events"] == EVENTS
    np.testing.assert_array_equal(back["P2.x"], run["P2.x"])
    del run.info["events"]


def test_the_model_hash_names_what_ran(compiled, run):
    solver = compiled("double_pendulum")
    plan = fccgen.api.plan_model(DOUBLE)
    assert run.info["model"]["hash"] == model_hash(plan)         # the file, read again
    assert run.info["model"]["structure_hash"] == solver.module.STRUCTURE_HASH
    heavier = solver.with_parameters({"bodies.rod2.mass": 0.9}).simulate(t_end=0.01)
    assert heavier.info["model"]["hash"] != run.info["model"]["hash"]
    assert heavier.info["model"]["structure_hash"] == run.info["model"]["structure_hash"]
    numeric = fccgen.load_numeric(DOUBLE).simulate(t_end=0.01)
    assert numeric.info["model"]["hash"] == run.info["model"]["hash"]


def test_the_csv_stays_a_plain_table(run, tmp_path):
    path = run.save(tmp_path / "run.csv")
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == run.names and len(rows) == len(run.t) + 1     # no comment lines
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table, run.table())
    meta = json.loads(sidecar_path(path).read_text())
    assert sidecar_path(path).name == "run.meta.json"
    assert meta["file"] == "run.csv" and meta["columns"] == run.names
    assert meta["info"]["method"] == "dopri5"


def test_a_sidecar_of_another_version_is_ignored(run, tmp_path):
    path = run.save(tmp_path / "run.csv")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-1]))              # the CSV edited by another program
    with pytest.warns(ResultMetadataWarning, match="describes another version of run.csv"):
        back = Result.load(path)
    assert back.info == {} and len(back.t) == len(run.t) - 1
    sidecar_path(path).unlink()
    assert Result.load(path).info == {}               # no sidecar: no metadata, no warning


def test_hdf5_holds_the_columns_in_order_and_the_events_table(run, tmp_path):
    import h5py
    run.info["events"] = EVENTS
    try:
        path = run.save(tmp_path / "run.h5")
    finally:
        del run.info["events"]
    with h5py.File(path, "r") as f:
        assert list(f)[:3] == ["t", "P1.x", "P1.y"]
        np.testing.assert_array_equal(f["P2.y"][()], run["P2.y"])
        assert list(f["events"]) == list(EVENTS[0])
        np.testing.assert_array_equal(f["events/time"][()], [0.25, 0.5])
        assert [n.decode() for n in f["events/name"][()]] == ["latch1", "stop1"]
    foreign = tmp_path / "other.h5"
    with h5py.File(foreign, "w") as f:
        f["t"] = np.zeros(3)
    with pytest.raises(ValueError, match="other.h5: not a result file written by fccgen"):
        Result.load(foreign)


def test_without_h5py_hdf5_is_refused_before_the_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "h5py", None)          # import h5py now fails
    with pytest.raises(HostError, match=r"need h5py.*pip install 'fccgen\[hdf5\]'"):
        check_output(tmp_path / "r.h5")
    build = tmp_path / "gen"
    with pytest.raises(HostError, match=r"fccgen\[hdf5\]"):
        fccgen.simulate(DOUBLE, out=tmp_path / "r.h5", build_dir=build)
    from fccgen.cli import main
    assert main(["simulate", str(DOUBLE), "--build-dir", str(build), "--out",
                 str(tmp_path / "r.h5")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("fccgen: error: HDF5 results (.h5) need h5py") and "[hdf5]" in err
    assert not build.exists() and list(tmp_path.iterdir()) == []   # nothing ran
