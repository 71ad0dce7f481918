"""The work-precision ladder (fccgen.bench.accuracy, fccgen.bench.accuracy_report) on a cheap model,
and the command line ``fccgen bench MODEL --accuracy``."""
from __future__ import annotations

import csv
import importlib.util
import math

import numpy as np
import pytest

from conftest import EXAMPLES, REFERENCE
from fccgen.bench.accuracy import (COLUMNS, Ladder, Reference, Variant, reference_from_table,
                                   run_ladder, run_one)
from fccgen.bench.accuracy_report import bench_accuracy
from fccgen.bench.accuracy_report import read_csv
from fccgen.cli import main
from fccgen.errors import SimulationError
from fccgen.results.result import Result

DOUBLE = EXAMPLES / "double_pendulum.yaml"
STEPS = (0.05, 0.025, 0.0125)
HAS_MATPLOTLIB = importlib.util.find_spec("matplotlib") is not None


@pytest.fixture(scope="module")
def ladder_report(build_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("accuracy")
    report = bench_accuracy(DOUBLE, build_dir, out, t_end=1.0, output_dt=0.05, steps=STEPS,
                            methods=["rk4"], numeric_rungs=1)
    return report, out


def test_the_csv_has_the_expected_columns_and_one_row_per_run(ladder_report):
    report, out = ladder_report
    path = out / "double_pendulum_accuracy.csv"
    with open(path, newline="") as fh:
        header = next(csv.reader(fh))
    assert header == COLUMNS
    for col in ("method", "value", "error", "cpu_time", "steps", "rhs_evaluations",
                "max_constraint_error"):
        assert col in header
    rows = read_csv(path)
    # rk4 with and without projection at 3 steps (compiled), each also numeric at 1 rung
    assert len(rows) == 2 * len(STEPS) + 2
    assert all(r.status == "ok" for r in rows)
    assert {r.version for r in rows} == {"compiled", "numeric"}


def test_errors_fall_as_the_steps_shrink(ladder_report):
    report, _ = ladder_report
    for project in (True, False):
        errs = [r.error for r in report.rows
                if r.version == "compiled" and r.project == project]
        assert len(errs) == len(STEPS)
        # RK4 is 4th order: halving the step divides the error by ~16; at these coarse
        # steps on a chaotic model, at least 4 leaves room for pre-asymptotic behaviour.
        for coarse, fine in zip(errs, errs[1:]):
            assert fine < coarse / 4, errs


def test_numeric_and_compiled_rows_measure_the_same_trajectory(ladder_report):
    report, _ = ladder_report
    for r in (r for r in report.rows if r.version == "numeric"):
        twin = next(c for c in report.rows if c.version == "compiled"
                    and c.project == r.project and c.value == r.value)
        # The two versions agree to ~1e-12 per step (docs/design.md §6); over 20 steps
        # their errors against the same reference differ by far less than 1e-9 m.
        assert abs(r.error - twin.error) < 1e-9
        assert r.steps == twin.steps and r.rhs_evaluations == twin.rhs_evaluations


def test_the_summary_names_the_reference_and_the_fastest_run_per_level(ladder_report):
    report, out = ladder_report
    text = (out / "double_pendulum_accuracy.txt").read_text()
    assert text.startswith("reference: converged: ")
    assert "fastest run at each accuracy level" in text
    assert "<= 1e-03 m: rk4 (compiled" in text
    assert "cost of projection" in text and "numeric version (NumPy)" in text
    table = (out / "double_pendulum_accuracy.md").read_text()
    assert table.count("\n| rk4 | ") == len(report.rows)       # one line per run
    best = min(r.error for r in report.rows)
    # The converged reference (a quarter of the finest step) is well below every run.
    assert report.reference.kind == "converged" and best > 0


def test_the_plot_is_written_when_matplotlib_is_installed(ladder_report):
    report, out = ladder_report
    if not HAS_MATPLOTLIB:
        assert "png" not in report.files
        assert any("PNG plot skipped" in n for n in report.notes)
        pytest.skip("matplotlib is not installed: checked that the plot was reported "
                    "as skipped instead")
    png = out / "double_pendulum_accuracy.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_svg_plot_needs_no_optional_dependency(ladder_report):
    _, out = ladder_report
    svg = (out / "double_pendulum_accuracy.svg").read_text()
    assert svg.startswith("<svg") and svg.count("<polyline") == 4   # 4 curves
    assert "rk4 (compiled, no projection)" in svg


# -- failures are recorded, bugs are not hidden -------------------------------------------

class _Raising:
    """A solver stand-in whose simulate raises the given exception."""

    def __init__(self, exc):
        self.exc = exc

    def simulate(self, **kwargs):
        raise self.exc


def _ref():
    return Reference("converged", "test", np.array([0.0, 0.5, 1.0]),
                     {"P": {"P.x": np.zeros(3), "P.y": np.zeros(3)}})


@pytest.mark.parametrize("exc, status", [
    (SimulationError("position projection did not converge at t = 0.3"), "failed"),
    (ValueError("unknown method 'rk4'; available: dopri5"), "unsupported"),
    (TypeError("simulate() got an unexpected keyword argument 'rtol'"), "unsupported"),
])
def test_a_run_that_stops_is_recorded_with_its_reason(exc, status):
    row = run_one(_Raising(exc), Variant("rk4", True), "dt", 0.1, _ref(), Ladder((0.1,)),
                  "m")
    assert row.status == status and row.failure == str(exc)
    assert math.isnan(row.error)


def test_an_unexpected_exception_is_raised_not_recorded():
    with pytest.raises(KeyError):
        run_one(_Raising(KeyError("bug")), Variant("rk4", True), "dt", 0.1, _ref(),
                Ladder((0.1,)), "m")


def test_an_unsupported_method_gets_one_row_not_one_per_rung():
    class Solver(_Raising):
        plan = type("P", (), {"model": type("M", (), {"name": "m"})})
    seen = []
    rows = run_ladder(Solver(ValueError("unknown method 'rk4'; available: x")), _ref(),
                      Ladder((0.5, 0.25, 0.125)), [Variant("rk4", True)],
                      progress=seen.append)
    assert [r.status for r in rows] == ["unsupported"]
    # progress counts the planned runs; the skipped rungs jump to the end
    assert [(e.stage, e.done, e.total) for e in seen] == [("accuracy", 0, 3),
                                                         ("accuracy", 3, 3)]


def test_the_error_is_the_largest_distance_and_times_must_match():
    ref = _ref()
    cols = {"P.x": np.array([0.0, 0.3, 0.0]), "P.y": np.array([0.0, 0.4, 0.1])}
    assert ref.error(Result(np.array([0.0, 0.5, 1.0]), cols)) == (0.5, 0.5)
    with pytest.raises(ValueError, match="output times"):
        ref.error(Result(np.array([0.0, 0.4, 1.0]), cols))


def test_a_published_table_is_read_with_its_comments_and_header():
    ref = reference_from_table(REFERENCE / "mbsbenchmark_A02_solution_data_B0.csv", "B0")
    assert ref.kind == "published" and len(ref.t) == 401
    assert ref.output_dt == pytest.approx(0.05) and ref.t_end == pytest.approx(20.0)
    assert ref.points["B0"]["B0.y"][0] == 1.0
    a01 = reference_from_table(REFERENCE / "mbsbenchmark_A01_solution_data.txt", "P")
    assert len(a01.t) == 4001 and a01.points["P"]["P.x"][0] == -1.0


# -- command line -------------------------------------------------------------------------

def test_cli_bench_accuracy_writes_the_table_and_summary(build_dir, tmp_path, capsys):
    code = main(["bench", str(DOUBLE), "--accuracy", "--out-dir", str(tmp_path),
                 "--build-dir", str(build_dir), "--t-end", "0.2", "--methods", "rk4",
                 "--numeric-rungs", "0", "-q"])
    out = capsys.readouterr().out
    assert code == 0
    assert "fastest run at each accuracy level" in out
    rows = read_csv(tmp_path / "double_pendulum_accuracy.csv")
    assert len(rows) == 10 and {r.version for r in rows} == {"compiled"}   # 2 x 5 rungs
    assert (tmp_path / "double_pendulum_accuracy.txt").exists()


def test_cli_bench_accuracy_against_a_published_reference(build_dir, tmp_path, capsys):
    code = main(["bench", str(EXAMPLES / "a01_pendulum.yaml"), "--accuracy",
                 "--out-dir", str(tmp_path), "--build-dir", str(build_dir),
                 "--t-end", "5", "--methods", "rk4", "--numeric-rungs", "0", "-q",
                 "--reference", str(REFERENCE / "mbsbenchmark_A01_solution_data.txt"),
                 "--reference-point", "P"])
    out = capsys.readouterr().out
    assert code == 0
    assert "reference: published: " in out and "up to t = 5" in out


def test_cli_bench_accuracy_rejects_an_unknown_method(build_dir, tmp_path, capsys):
    code = main(["bench", str(DOUBLE), "--accuracy", "--out-dir", str(tmp_path),
                 "--build-dir", str(build_dir), "--methods", "euler", "-q"])
    assert code == 1
    assert "unknown method 'euler'" in capsys.readouterr().err
