"""Sweeps never lose finished work (docs/sweeps.md, docs/reliability.md): rows are
written as they finish, every run has a time limit, the table's place and Dask are
checked before anything is built, and Ctrl-C or a failed cluster end in one paragraph
that says how many rows were saved and where.

Every failure here is provoked at a chosen point (a progress callback or a patched
function that raises), never by racing a signal or a process against the sweep."""
from __future__ import annotations

import csv
import json
import shutil
import sys

import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.errors import HostError
from fccgen.results.provenance import model_hash
from fccgen.sweep import SweepInterrupted, SweepStopped
from fccgen.sweep import sweep as run_sweep

DOUBLE = EXAMPLES / "double_pendulum.yaml"
MASSES = [0.4, 0.6, 0.9, 1.2]
SETS = {"bodies.rod2.mass": MASSES, "simulate.t_end": [0.05]}


def read_table(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def raise_at(done: int, exc: BaseException):
    """A progress callback that raises ``exc`` when ``done`` runs have ended (the point
    where Ctrl-C or a lost connection reaches a waiting sweep)."""
    def progress(event):
        if event.done == done:
            raise exc
    return progress


@pytest.fixture(scope="module")
def solver(build_dir):
    return fccgen.load(DOUBLE, build_dir)


def test_rows_reach_the_partial_file_as_runs_finish(solver, tmp_path):
    out = tmp_path / "sweep.csv"
    partial = tmp_path / "sweep.partial.csv"
    seen = []

    def look(event):
        if event.done:       # the row of the run that just ended is on the disk
            seen.append(len(read_table(partial)))
    table = run_sweep(solver, SETS, workers=1, out=out, progress=look)
    assert seen == [1, 2, 3, 4]
    assert not partial.exists()                  # the table replaced it
    rows = read_table(out)
    assert [int(r["run"]) for r in rows] == [1, 2, 3, 4]
    assert [float(r["bodies.rod2.mass"]) for r in rows] == MASSES
    assert [r["status"] for r in rows] == ["ok"] * 4 and table.failed == 0


def test_ctrl_c_keeps_the_rows_that_finished(solver, tmp_path):
    out = tmp_path / "sweep.csv"
    with pytest.raises(SweepInterrupted) as caught:
        run_sweep(solver, SETS, workers=1, out=out,
                  progress=raise_at(2, KeyboardInterrupt()))
    exc = caught.value
    assert isinstance(exc, KeyboardInterrupt)       # still Ctrl-C for Python callers
    partial = tmp_path / "sweep.partial.csv"
    text = str(exc)
    assert text.startswith("sweep stopped after 2 of 4 runs: interrupted (Ctrl-C). ")
    assert f"The 2 finished rows are saved in {partial}" in text and "\n" not in text
    assert exc.saved == 2 and exc.partial_path == partial and len(exc.rows) == 2
    rows = read_table(partial)
    assert len(rows) == 2 and all(r["status"] == "ok" for r in rows)
    assert sorted(int(r["run"]) for r in rows) == [1, 2]     # one thread: in order
    assert not out.exists()


def test_a_failed_cluster_keeps_the_rows_and_says_so(solver, tmp_path):
    """What a scheduler that goes away raises while the sweep waits for it."""
    from distributed.comm.core import CommClosedError
    out = tmp_path / "sweep.csv"
    with pytest.raises(SweepStopped) as caught:
        run_sweep(solver, SETS, workers=1, out=out,
                  progress=raise_at(1, CommClosedError("in <TCP (closed)>: Stream is "
                                                       "closed")))
    exc = caught.value
    assert isinstance(exc, HostError)
    assert str(exc).startswith("sweep stopped after 1 of 4 runs: the Dask cluster at a "
                               "local cluster of 1 thread(s) failed (CommClosedError: ")
    assert "The 1 finished row is saved in" in str(exc)
    assert len(read_table(tmp_path / "sweep.partial.csv")) == 1


def test_workers_that_cannot_see_the_build_folder_stop_the_sweep(solver, build_dir,
                                                                 tmp_path):
    """Workers in another process load the compiled module by its folder's path: a
    folder they cannot see (here moved away after the load) stops the sweep before any
    run, with the folder and what the workers need."""
    from dask.distributed import LocalCluster
    shutil.copytree(build_dir / "double_pendulum", tmp_path / "build" / "double_pendulum")
    moved = fccgen.load(DOUBLE, tmp_path / "build")      # the cached module: no compile
    (tmp_path / "build").rename(tmp_path / "elsewhere")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        with pytest.raises(SweepStopped) as caught:
            run_sweep(moved, SETS, scheduler=cluster.scheduler_address,
                      out=tmp_path / "t.csv")
    text = str(caught.value)
    assert text.startswith(f"sweep stopped after 0 of 4 runs: the workers of "
                           f"{cluster.scheduler_address} could not load the compiled solver")
    assert str(tmp_path / "build" / "double_pendulum") in text
    assert "every worker must see the build folder at the same path" in text
    assert text.endswith("No run had finished, so nothing was written.")
    assert not (tmp_path / "t.partial.csv").exists()


def test_a_task_that_raises_gives_a_failed_row(solver, monkeypatch):
    """An error no run reports by itself (a bug, a worker that died) fails its row
    only; the other runs go on."""
    from fccgen.runtime import CompiledSolver
    original = CompiledSolver.simulate

    def simulate(self, *args, **kwargs):
        if self.plan.model.bodies["rod2"].mass == 0.6:
            raise RuntimeError("the worker went away")
        return original(self, *args, **kwargs)
    monkeypatch.setattr(CompiledSolver, "simulate", simulate)
    table = run_sweep(solver, SETS, workers=1)
    assert [r["status"] for r in table.rows] == ["ok", "failed", "ok", "ok"]
    assert table.rows[1]["error"] == ("the task ended in RuntimeError: the worker went "
                                      "away")


def test_an_endless_run_is_stopped_by_its_time_limit(solver):
    """10^8 steps of 1 us (minutes of work) against a limit of 0.2 s: the limit is
    read when the integrator pauses (about every 0.5 s), so the run ends at its first
    pause, whatever the machine's load."""
    table = run_sweep(solver, {"simulate.dt": [1e-6], "simulate.t_end": [100.0]},
                      workers=1, run_timeout=0.2)
    (row,) = table.rows
    assert row["status"] == "timeout" and table.failed == 1 and table.timed_out == 1
    assert row["error"].startswith("stopped by the run time limit of 0.2 s (wall time) "
                                   "at t = ")
    assert "of 100" in row["error"] and "final.P2.x" not in row
    assert solver.simulate(t_end=0.01)["P2.x"].size                 # solver unharmed


def test_a_time_limit_the_runs_do_not_reach_changes_nothing(solver):
    plain = run_sweep(solver, SETS, workers=1)
    limited = run_sweep(solver, SETS, workers=1, run_timeout=3600)
    for a, b in zip(plain.rows, limited.rows):
        assert b["status"] == "ok" and a["final.P2.x"] == b["final.P2.x"]


def test_the_table_carries_its_provenance(solver, tmp_path):
    out = tmp_path / "sweep.csv"
    run_sweep(solver, SETS, workers=1, out=out, outputs="P2.y:min")
    meta = json.loads((tmp_path / "sweep.meta.json").read_text())
    info = meta["info"]
    assert info["fccgen_version"] == fccgen.__version__
    assert info["model"]["hash"] == model_hash(solver.plan)
    assert info["model"]["structure_hash"] == solver.module.STRUCTURE_HASH
    assert (info["method"], info["dt"], info["t_end"]) == ("rk4", 1e-3, 5.0)
    assert info["solver"]["position_tol"] == solver.position_tol
    assert info["sets"] == {k: list(v) for k, v in SETS.items()}
    assert info["outputs"] == ["P2.y:min"] and info["rows"] == 4
    assert meta["columns"][:3] == ["run", "bodies.rod2.mass", "simulate.t_end"]
    for row, mass in zip(read_table(out), MASSES):     # each row: the numbers it ran
        params = {"bodies.rod2.mass": mass, "simulate.t_end": 0.05}
        assert row["model_hash"] == model_hash(solver.with_parameters(params).plan)
    assert len({r["model_hash"] for r in read_table(out)}) == 4


def test_a_parquet_table_carries_its_provenance(solver, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "sweep.parquet"
    run_sweep(solver, SETS, workers=1, out=out)
    table = pq.read_table(out)
    info = json.loads(table.schema.metadata[b"fccgen_info"])
    assert info["model"]["hash"] == model_hash(solver.plan) and info["rows"] == 4
    assert table.column("run").to_pylist() == [1, 2, 3, 4]
    assert not (tmp_path / "sweep.partial.csv").exists()


# -- the command line ----------------------------------------------------------------

def cli(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_ctrl_c_ends_in_one_paragraph_with_status_130(build_dir, tmp_path, capsys,
                                                           monkeypatch):
    """Ctrl-C arrives as the second finished row has been written."""
    from fccgen.sweep import table as sweep_table
    add = sweep_table.PartialWriter.add

    def add_then_interrupt(self, row):
        add(self, row)
        if self.count == 2:
            raise KeyboardInterrupt
    monkeypatch.setattr(sweep_table.PartialWriter, "add", add_then_interrupt)
    out = tmp_path / "sweep.csv"
    code, text, err = cli(["sweep", DOUBLE, "--build-dir", build_dir, "-q", "--workers",
                           "1", "--set", "bodies.rod2.mass=0.4,0.6,0.9",
                           "--set", "simulate.t_end=0.05", "--out", out], capsys)
    assert code == 130 and text == ""
    partial = tmp_path / "sweep.partial.csv"
    assert err == (f"fccgen: sweep stopped after 2 of 3 runs: interrupted (Ctrl-C). The 2 "
                   f"finished rows are saved in {partial} (CSV, in the order the runs "
                   f"ended; column run gives each row's place in the sweep); sweep.csv was "
                   f"not written. Run the same sweep with --resume to keep them and run "
                   f"the rest.\n")
    assert len(read_table(partial)) == 2 and not out.exists()
    # the next sweep to the same table refuses to overwrite them, before building
    code, text, err = cli(["sweep", DOUBLE, "--build-dir", tmp_path / "build", "-q",
                           "--set", "bodies.rod2.mass=1", "--out", out], capsys)
    assert code == 1 and f"{partial} holds the rows of an earlier sweep" in err
    assert "run the same sweep with --resume" in err
    assert not (tmp_path / "build").exists() and len(read_table(partial)) == 2


def test_resume_keeps_the_rows_and_runs_the_rest(solver, tmp_path):
    """A sweep stopped after 2 of 4 runs, the second row's last line cut as by a
    killed process: --resume keeps run 1 as written, runs 2 to 4, and the table is
    the one a sweep without a stop gives."""
    out = tmp_path / "sweep.csv"
    partial = tmp_path / "sweep.partial.csv"
    with pytest.raises(SweepInterrupted):
        run_sweep(solver, SETS, workers=1, out=out,
                  progress=raise_at(2, KeyboardInterrupt()))
    kept = read_table(partial)[0]
    partial.write_bytes(partial.read_bytes()[:-20])          # run 2's line cut short
    ran = []
    table = run_sweep(solver, SETS, workers=1, out=out, resume=True,
                      progress=lambda e: ran.append(e.done))
    assert ran == [1, 2, 3, 4]            # 1 kept, then the three that ran
    assert not partial.exists()
    rows = read_table(out)
    assert rows[0] == kept                               # as written before the stop
    whole = run_sweep(solver, SETS, workers=1)
    for row, again in zip(rows, whole.rows):
        assert float(row["final.P2.x"]) == again["final.P2.x"]
    assert table.info["resumed_rows"] == 1


def test_resume_refuses_the_rows_of_another_sweep(solver, tmp_path):
    out = tmp_path / "sweep.csv"
    with pytest.raises(SweepInterrupted):
        run_sweep(solver, SETS, workers=1, out=out,
                  progress=raise_at(1, KeyboardInterrupt()))
    other = {"bodies.rod2.mass": [0.5, *MASSES[1:]], "simulate.t_end": [0.05]}
    with pytest.raises(ValueError, match="its row of run 1 is not a run of this sweep"):
        run_sweep(solver, other, workers=1, out=out, resume=True)
    with pytest.raises(ValueError, match="was written by a sweep with other columns"):
        run_sweep(solver, SETS, workers=1, out=out, resume=True, outputs="P2.x:max")
    assert len(read_table(tmp_path / "sweep.partial.csv")) == 1     # left as it was


def test_cli_an_unwritable_table_stops_before_the_build(tmp_path, capsys):
    (tmp_path / "file").write_text("in the way")
    build = tmp_path / "build"
    code, text, err = cli(["sweep", DOUBLE, "--build-dir", build, "-q", "--set",
                           "bodies.rod2.mass=1", "--out", tmp_path / "file" / "t.csv"],
                          capsys)
    assert code == 1 and text == ""
    assert err.startswith(f"fccgen: error: cannot write the sweep table in "
                          f"{tmp_path / 'file'}: ") and err.count("\n") == 1
    assert not build.exists()


def test_cli_without_dask_stops_before_the_build(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)   # import fails
    build = tmp_path / "build"
    code, text, err = cli(["sweep", DOUBLE, "--build-dir", build, "-q", "--set",
                           "bodies.rod2.mass=1", "--out", tmp_path / "t.csv"], capsys)
    assert code == 1 and text == ""
    assert err == ("fccgen: error: fccgen sweep needs Dask, which is not installed. To "
                   "fix it, pip install 'fccgen[sweep]' (dask[distributed])\n")
    assert not build.exists() and not list(tmp_path.iterdir())


def test_cli_run_timeout_is_checked(build_dir, tmp_path, capsys):
    code, text, err = cli(["sweep", DOUBLE, "--build-dir", build_dir, "-q", "--set",
                           "bodies.rod2.mass=1", "--run-timeout", "0", "--out",
                           tmp_path / "t.csv"], capsys)
    assert code == 1 and "--run-timeout must be a positive number of seconds" in err
    assert not list(tmp_path.iterdir())
