"""The error target's interface: what it refuses, what it records, the command line,
the numeric version, and its warnings (the accuracy itself: test_error_target.py)."""
from __future__ import annotations

import warnings
from types import SimpleNamespace

import pytest

from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.errors import RunWarning
from fccgen.results.result import Result
from fccgen.target_error.choice import Choice
from fccgen.target_error.estimate import Estimate, converged, singular_warning
from fccgen.target_error.run import report

DOUBLE = EXAMPLES / "double_pendulum.yaml"
SHORT = dict(t_end=1.0, output_dt=0.01)


def quiet(solver, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        return solver.simulate(**kwargs)


@pytest.fixture(scope="module")
def double(compiled):
    return compiled("double_pendulum")


@pytest.fixture(scope="module")
def double_run(double):
    return quiet(double, error=1e-5, **SHORT)


@pytest.mark.parametrize("extra, named", [(dict(dt=1e-3), "dt"), (dict(rtol=1e-8), "rtol"),
                                          (dict(project=False), "project"),
                                          (dict(alpha=5.0), "alpha")])
def test_settings_the_target_chooses_are_refused(double, extra, named):
    with pytest.raises(ValueError, match=f"chooses the method's settings itself: leave "
                                         f"out {named}"):
        double.simulate(error=1e-4, **SHORT, **extra)


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), float("inf"), "x"])
def test_an_error_that_is_not_a_positive_number_is_refused(double, bad):
    with pytest.raises(ValueError, match="error must be a positive number"):
        double.simulate(error=bad, **SHORT)


def test_error_on_a_missing_column_names_it(double):
    with pytest.raises(ValueError, match="no column 'P9.x'"):
        double.simulate(error=1e-4, error_on=["P9.x"], **SHORT)


def test_a_method_outside_the_candidates_is_refused(double):
    with pytest.raises(ValueError, match="method 'baumgarte' cannot be chosen"):
        double.simulate(error=1e-4, method="baumgarte", **SHORT)


def test_the_run_records_target_estimate_choice_and_costs(double_run):
    info = double_run.info
    assert info["error_target"] == 1e-5 and info["error_estimate"] > 0
    assert info["error_on"] == [f"{p}.{c}" for p in ("P1", "P2") for c in "xyz"]
    acc = info["accuracy"]
    assert acc["method"] == info["method"] in ("rk4", "dopri5")
    assert acc["choice"].startswith(f"{acc['method']} with {acc['setting']} = ")
    assert {c["method"] for c in acc["candidates"]} >= {"rk4", "dopri5"}
    assert all(acc["cost"][k] > 0 for k in ("pilot", "run", "estimate"))
    assert acc["estimate"].startswith("Richardson")


def test_the_record_survives_the_result_files(double_run, tmp_path):
    for suffix in (".csv", ".npz"):
        back = Result.load(double_run.save(tmp_path / f"r{suffix}"))
        assert back.info["error_estimate"] == double_run.info["error_estimate"]
        assert back.info["accuracy"]["choice"] == double_run.info["accuracy"]["choice"]


def test_error_on_a_point_measures_that_point_only(double):
    r = quiet(double, error=1e-5, error_on=["P1"], **SHORT)
    assert r.info["error_on"] == ["P1.x", "P1.y", "P1.z"]
    whole = quiet(double, error=1e-5, **SHORT)
    # P1 is the inner point: its estimate is no larger than that of both points
    # at the same choice
    if r.info["accuracy"]["choice"] == whole.info["accuracy"]["choice"]:
        assert r.info["error_estimate"] <= whole.info["error_estimate"]


def test_method_restricts_the_choice_to_that_method(double):
    r = quiet(double, error=1e-5, method="rk4", **SHORT)
    assert r.info["method"] == "rk4"
    assert [c["method"] for c in r.info["accuracy"]["candidates"]] == ["rk4"]
    # the step divides the output interval (every output time is a step)
    n = SHORT["output_dt"] / r.info["dt"]
    assert abs(n - round(n)) < 1e-9


def test_the_numeric_version_takes_the_same_target(numeric, double_run):
    r = quiet(numeric("double_pendulum"), error=1e-5, **SHORT)
    # the same pilot on the same trajectory: the same method, and a setting and an
    # estimate that agree closely. The setting is a continuous function of the pilot's
    # rung differences (~1e-7 here), which the versions' ~1e-12 per step moves by
    # about 1e-5 relative at most (measured 2e-7).
    ours, theirs = r.info["accuracy"], double_run.info["accuracy"]
    assert ours["method"] == theirs["method"]
    assert ours["value"] == pytest.approx(theirs["value"], rel=1e-5)
    assert r.info["error_estimate"] == pytest.approx(double_run.info["error_estimate"],
                                                     rel=1e-3)


def test_a_run_past_singular_positions_warns_rather_than_promises():
    info = dict(error_estimate=1e-4, singular_position_factorisations=3,
                dof_changes=[dict(t=0.5, dof_before=1, dof_after=2)])
    [text] = singular_warning(info)
    assert "3 factorisations dropped constraint rows" in text and "t = 0.5" in text
    assert "not a promise" in text
    assert singular_warning(dict(error_estimate=1e-4)) == []


def test_the_command_line_prints_the_choice_and_the_estimate(build_dir, capsys, tmp_path):
    out = tmp_path / "r.csv"
    code = main(["simulate", str(DOUBLE), "--error", "1e-5", "--t-end", "1",
                 "--build-dir", str(build_dir), "-q", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    assert "error target 1e-05: chose " in text and "estimated error " in text
    assert Result.load(out).info["error_target"] == 1e-5


@pytest.mark.parametrize("args, message", [
    (["--error-on", "P1"], "--error-on measures the error of --error"),
    (["--error", "1e-4", "--dt", "0.01"], "--error chooses the step or tolerance itself"),
])
def test_the_command_line_refuses_what_does_not_go_with_error(build_dir, capsys, args,
                                                               message):
    code = main(["simulate", str(DOUBLE), "--build-dir", str(build_dir), "-q", *args])
    assert code == 1 and message in capsys.readouterr().err


def _estimate(value, roundoff=0.0, reused=False):
    return Estimate(value, 1.0, 16.0, roundoff, 0.02,
                    dict(event_time_error=0.0, event_position_error=0.0), reused=reused)


def test_a_repeat_converged_when_its_estimate_fell_as_the_order_says():
    first = Choice("rk4", "dt", 0.01, 5e-7, 100.0, 4.0)
    again = Choice("rk4", "dt", 0.005, 5e-7, 200.0, 4.0)
    # halving an order-4 step divides the error by 16
    assert converged(first, again, _estimate(1.6e-5), _estimate(1e-6))
    assert converged(first, again, _estimate(1.6e-5), _estimate(4e-6))
    assert not converged(first, again, _estimate(1.6e-5), _estimate(5e-6))


def test_a_repeat_whose_error_does_not_fall_warns_that_it_is_no_promise():
    """A motion whose error does not fall with the step (a branch point, chaos): the
    repeated run's estimate stays high, and the warning says why rather than naming a
    step that would reach the target."""
    first = Choice("rk4", "dt", 0.01, 5e-7, 100.0, 4.0, reason="first")
    again = Choice("rk4", "dt", 0.005, 5e-7, 200.0, 4.0, reason="again")
    steps = dict(rhs_evaluations=400, newton_iterations=0, steps=100, project=False)
    result = SimpleNamespace(info=dict(steps))
    frame = SimpleNamespace(cost=300.0, what=SimpleNamespace(columns=["P.x"]),
                            t_piece=0.1, output_dt=0.01, singular=None)
    with pytest.warns(RunWarning) as seen:
        report(result, SimpleNamespace(info=dict(steps)), frame, again,
               _estimate(8e-6, reused=True), 1e-6, (first, _estimate(1.6e-5), 600.0))
    [text] = [str(w.message) for w in seen]
    assert "exceeds the target" in text and "does not fall with the step" in text
    assert "would reach" not in text
    cost = result.info["accuracy"]["cost"]
    # the first run is the repeat's twin: no estimate of its own is paid for
    assert cost == dict(pilot=300.0, run=400.0, estimate=0.0, repeat=600.0, whole=1300.0)
    assert result.info["accuracy"]["repeated"]["estimate"] == 1.6e-5
