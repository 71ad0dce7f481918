"""Sweeps (docs/design.md §5, ``fccgen sweep``): one compiled model, many numbers, on
Dask; each row is what a separate run with those numbers gives."""
from __future__ import annotations

import csv

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.sweep import combinations, parse_sets
from fccgen.sweep import sweep as run_sweep

DOUBLE = EXAMPLES / "double_pendulum.yaml"
MASSES = [0.4, 0.6, 0.9]
T_END = 0.5


def run(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def read_table(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def expected_row(solver, mass):
    """A separate run of the double pendulum with rod 2's mass set."""
    return solver.with_parameters({"bodies.rod2.mass": mass}).simulate(t_end=T_END)


def test_sets_and_their_combinations():
    sets = parse_sets(["a.b=1,2", "c[0]=3"])
    assert sets == {"a.b": [1.0, 2.0], "c[0]": [3.0]}
    assert combinations({"a": [1, 2], "b": [3, 4]}) == [
        {"a": 1, "b": 3}, {"a": 1, "b": 4}, {"a": 2, "b": 3}, {"a": 2, "b": 4}]


def test_cli_sweep_gives_the_rows_of_separate_runs(build_dir, tmp_path, capsys):
    out = tmp_path / "sweep.csv"
    code, text, err = run(["sweep", DOUBLE, "--build-dir", build_dir, "-q",
                           "--set", "bodies.rod2.mass=" + ",".join(map(str, MASSES)),
                           "--set", f"simulate.t_end={T_END}", "--out", out], capsys)
    assert code == 0, err
    assert "3 runs (0 failed)" in text and str(out) in text
    rows = read_table(out)
    assert [float(r["bodies.rod2.mass"]) for r in rows] == MASSES
    solver = fccgen.load(DOUBLE, build_dir)
    for row, mass in zip(rows, MASSES):
        r = expected_row(solver, mass)
        assert row["status"] == "ok" and row["error"] == ""
        # the same compiled code and numbers in a thread of this process, and floats
        # written in their exact shortest form: equal to the last bit
        for name in ("P1.x", "P1.y", "P2.x", "P2.y"):
            assert float(row[f"final.{name}"]) == r[name][-1]
        assert float(row["energy_drift"]) == r.info["energy_drift"]
        assert float(row["max_constraint_error"]) == r.info["max_constraint_error"]
        assert int(row["steps"]) == 500 and float(row["t_final"]) == T_END
        assert float(row["wall_time"]) > 0
    # the mass changes the motion: three different end points
    assert len({row["final.P2.x"] for row in rows}) == 3


def test_a_failed_run_is_a_row_with_its_error(build_dir):
    solver = fccgen.load(DOUBLE, build_dir)
    seen = []
    table = run_sweep(solver, {"simulate.dt": [1e-3, 0.05], "simulate.t_end": [0.1]},
                      workers=1, progress=seen.append)
    # structured progress: runs done of the total, each event also its message
    assert [(e.stage, e.done, e.total) for e in seen] == [("sweep", k, 2) for k in range(3)]
    assert seen[-1] == "sweep: 2 of 2 runs done"
    ok, failed = table.rows
    assert ok["status"] == "ok" and failed["status"] == "failed"
    assert "output_dt: must be a positive whole multiple of dt" in failed["error"]
    assert table.failed == 1 and "final.P2.x" not in failed


def test_workers_in_other_processes_unpickle_the_solver(build_dir):
    from dask.distributed import LocalCluster
    solver = fccgen.load(DOUBLE, build_dir)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        table = run_sweep(solver, {"bodies.rod2.mass": MASSES[:2],
                                   "simulate.t_end": [T_END]},
                          scheduler=cluster.scheduler_address)
    assert table.where == cluster.scheduler_address
    for row, mass in zip(table.rows, MASSES):
        r = expected_row(solver, mass)
        assert row["status"] == "ok", row["error"]
        # another process, the same module file and inputs: the same bits
        assert row["final.P2.x"] == r["P2.x"][-1] and row["final.P2.y"] == r["P2.y"][-1]


@pytest.mark.parametrize("args, words", [
    (["--set", "bodies.rod2.mass"], ["expected KEY=V1,V2"]),
    (["--set", "bodies.rod2.mass=1,heavy"], ["expected KEY=V1,V2"]),
    (["--set", "bodies.rod2.mas=1,2"], ["bodies.rod2.mas", "is not a number fccgen can set"]),
    (["--set", "bodies.rod2.mass=1,-2"], ["double_pendulum.yaml:", "must be a positive"]),
    (["--set", "bodies.rod2.mass=1", "--out", "table.txt"], ["table.txt", ".csv"]),
    (["--set", "bodies.rod2.mass=1", "--method", "euler"], ["unknown method 'euler'"]),
    (["--set", "bodies.rod2.mass=1", "--workers", "0"], ["--workers must be at least 1"]),
])
def test_bad_sweeps_stop_before_running(build_dir, tmp_path, capsys, args, words):
    if "--out" not in args:
        args = [*args, "--out", "table.csv"]
    args = [tmp_path / a if a.startswith("table.") else a for a in args]
    code, out, err = run(["sweep", DOUBLE, "--build-dir", build_dir, "-q", *args], capsys)
    assert code in (1, 2) and out == ""
    assert err.startswith("fccgen: error: ") and err.count("\n") == 1
    for w in words:
        assert w in err
    assert not list(tmp_path.iterdir())


def test_no_scheduler_at_the_address(build_dir, tmp_path):
    from fccgen.errors import HostError
    solver = fccgen.load(DOUBLE, build_dir)
    with pytest.raises(HostError, match="no Dask scheduler answers at tcp://127.0.0.1:9"):
        run_sweep(solver, {"bodies.rod2.mass": [1.0]}, scheduler="tcp://127.0.0.1:9",
                  connect_timeout=1.0, out=tmp_path / "t.csv")
    assert not list(tmp_path.iterdir())        # no partial file to block the next sweep
    assert np.isfinite(solver.simulate(t_end=0.01)["P2.x"][-1])   # the solver still runs


def test_a_sweep_table_written_as_parquet_keeps_every_row(build_dir, tmp_path):
    """The same table as CSV and as Parquet: the Parquet columns are typed (floats stay
    the exact doubles, not their text) and read back equal to the CSV's values."""
    pq = pytest.importorskip("pyarrow.parquet")
    from fccgen.sweep import SweepTable
    table = SweepTable(keys=["m"], rows=[{"m": 1.0, "steps": 500, "status": "ok", "error": "",
                              "final.x": 0.1 + 0.2},
                             {"m": 2.0, "steps": 500, "status": "failed",
                              "error": "diverged", "final.x": None}],
                       wall_time=1.0, where="local",
                       columns=["m", "steps", "status", "error", "final.x"])
    back = pq.read_table(table.save(tmp_path / "t.parquet")).to_pydict()
    assert back["m"] == [1.0, 2.0] and back["steps"] == [500, 500]
    assert back["final.x"] == [0.1 + 0.2, None] and back["error"] == ["", "diverged"]
    rows = read_table(table.save(tmp_path / "t.csv"))
    assert [float(r["final.x"] or "nan") for r in rows][0] == back["final.x"][0]
    assert not list(tmp_path.glob(".*.tmp"))          # written atomically


def test_rows_of_a_model_with_joints_name_its_bodies_not_the_lowering(build_dir):
    """Sweep rows carry the user's names only (result.names): a joint-form model's
    finals are its bodies' mass centres, never the points its joints were lowered to."""
    solver = fccgen.load(EXAMPLES / "four_bar_driven.yaml", build_dir)
    table = run_sweep(solver, {"simulate.t_end": [0.05]}, workers=1)
    r = solver.simulate(t_end=0.05)
    row = table.rows[0]
    finals = [k for k in table.columns if k.startswith("final.")]
    assert finals and all(k[len("final."):] in r.names for k in finals)
    for k in finals:
        assert row[k] == r[k[len("final."):]][-1]
