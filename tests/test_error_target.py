"""simulate(error=E): the error reached, its estimate and the cost of the choice,
against independent references (tests/error_references.py): A01's closed form, A02's
published table, A02's first 0.6 s against a converged run, the Lagrange top's
Euler-angle equations, Andrews' mechanism against its published equations (and
solution at t = 0.03), and a fine run of the solar array with its two latches.

What each case must show (docs/accuracy.md):
- the true error is at most E, or at most 3E with the run's own warning;
- the estimate info["error_estimate"] is within 10x of the true error;
- the run costs (in evaluations, deterministic counts) at most 2x the cheapest
  hand-tuned method and setting that meets E (tests/data/error_target_grid.json).
E = 1e-9 runs here for the top, the solar array, Andrews and A02's first 0.6 s: A01
over 2000 s at 1e-9 takes ~20 s of CPU (its figures are in docs/accuracy.md, from
benchmarks/error_target.py). A02 over 20 s is judged at 1e-3 only: its published table
has six digits, and past its flat positions no run converges below about 1e-4 m
(benchmarks/a02_convergence.py).
"""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import error_references as refs
from conftest import ROOT
from fccgen.errors import RunWarning, SimulationError
from fccgen.target_error.compare import compared, speeds

GRID = json.loads((ROOT / "tests" / "data" / "error_target_grid.json").read_text())
CASES = [(name, level) for name, case in refs.CASES.items() for level in case.levels]


@pytest.fixture(scope="module")
def solvers(build_dir, tmp_path_factory):
    model_dir = tmp_path_factory.mktemp("error_target")
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = refs.load(name, build_dir, model_dir)
        return cache[name]
    return get


@pytest.fixture(scope="module")
def references(solvers):
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = refs.CASES[name].reference(solvers(name))
        return cache[name]
    return get


def run_to(solver, error, **kwargs):
    """(result, warning texts) of an error-target run."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = solver.simulate(error=error, **kwargs)
    texts = [str(w.message) for w in seen if issubclass(w.category, RunWarning)]
    assert texts == result.info.get("warnings", []) or set(texts) <= set(
        result.info["warnings"])
    return result, texts


@pytest.fixture(scope="module")
def runs(solvers, references):
    cache = {}

    def get(name, level):
        if (name, level) not in cache:
            case = refs.CASES[name]
            solver = solvers(name)
            result, texts = run_to(solver, level, t_end=case.t_end,
                                   output_dt=case.output_dt)
            cache[name, level] = (result, texts,
                                  case.error(solver, result, references(name)))
        return cache[name, level]
    return get


def test_the_a01_closed_form_is_the_published_solution(references):
    data = np.loadtxt(refs.REFERENCE / "mbsbenchmark_A01_solution_data.txt", skiprows=1)
    x, y = refs.pendulum_exact(data[:, 0])
    # the table has six significant digits: rounding 5e-7, measured 7.1e-7 at most
    assert np.max(np.hypot(x - data[:, 1], y - data[:, 2])) < 1e-6


@pytest.mark.parametrize("name, level", CASES)
def test_the_error_reached_meets_the_target_and_the_estimate_tracks_it(runs, name, level):
    result, texts, true = runs(name, level)
    info = result.info
    assert info["error_target"] == level
    estimate = info["error_estimate"]
    over = [t for t in texts if "exceeds the target" in t]
    # at most E; at most 3E only when the run said its estimate exceeded E
    assert true <= level or (true <= 3 * level and over), (true, estimate, texts)
    assert (estimate > level) == bool(over)
    # the estimate within 10x of the truth either way
    assert true / 10 <= estimate <= 10 * true, (true, estimate)
    # only A02's motion passes singular positions (its chain lies flat at t = 0.72,
    # 1.25, ... s; the others keep their smallest kept singular value within 0.4 %)
    near = [t for t in texts if "comes near singular positions" in t]
    assert bool(near) == (name == "a02" and result.info["accuracy"]["pilot_piece"] > 0.72)


@pytest.mark.parametrize("name, level", CASES)
def test_the_choice_costs_at_most_twice_the_cheapest_hand_tuned_run(runs, name, level):
    result, _, _ = runs(name, level)
    meets = [r for r in GRID[name]["runs"] if r["error"] is not None
             and r["error"] <= level]
    assert meets, "the grid search found no run that meets this level"
    best = min(meets, key=lambda r: r["evaluations"])
    cost = result.info["accuracy"]["cost"]
    # the chosen method and setting (the run itself) against the grid's cheapest; the
    # pilot and the twin of the estimate are reported apart (docs/accuracy.md)
    assert cost["run"] <= 2 * best["evaluations"], (cost, best)


@pytest.mark.parametrize("level", refs.CASES["solar"].levels)
def test_the_latch_times_meet_the_target(runs, solvers, references, level):
    result, _, _ = runs("solar", level)
    fine = references("solar")
    solver = solvers("solar")
    names = [e["name"] for e in result.events]
    assert names == [e["name"] for e in fine.events] == ["panel_latch", "root_latch"]
    # the speed of the fastest compared point (every moving point) at each output
    v = speeds(fine, compared(solver.plan, solver.length_scale))
    for ours, ref in zip(result.events, fine.events):
        late = abs(ours["t"] - ref["t"])
        k = int(np.searchsorted(fine.t, ref["t"]))
        # a latch found late by dt leaves the points behind by about speed * dt
        assert late * max(v[k - 1], v[k]) <= level, (ours["name"], late)
    # the estimate includes what the event times move
    acc = result.info["accuracy"]
    assert acc["event_position_error"] <= result.info["error_estimate"]
    assert acc["event_time_error"] > 0


def test_a_run_whose_estimate_ends_above_the_target_is_repeated(runs):
    """Andrews' crank turns about 20 times faster at the end of the run than at the
    end of the pilot: the first choice at 1e-6 ends far above E, and the repeat at
    the setting its estimate names meets it."""
    result, texts, true = runs("andrews", 1e-6)
    acc = result.info["accuracy"]
    first = acc["repeated"]
    assert first is not None and first["estimate"] > 1e-6 > result.info["error_estimate"]
    assert acc["value"] < first["value"] and "repeated" in acc["choice"]
    cost = acc["cost"]
    assert cost["repeat"] > 0 and not texts
    # the first run is the repeat's coarse twin: no second twin runs
    assert cost["estimate"] == 0 and "the first run" in acc["estimate"]
    assert acc["twin_value"] == first["value"]
    assert cost["whole"] == cost["pilot"] + cost["run"] + cost["repeat"]


def test_a_candidate_that_cannot_win_stops_measuring_but_gives_the_growth(runs):
    """The solar array at 1e-3: rk4 at one step per output interval already costs more
    than dopri5 is predicted to; its coarse rung runs for the error's growth only."""
    result, _, _ = runs("solar", 1e-3)
    rows = {c["method"]: c for c in result.info["accuracy"]["candidates"]}
    assert rows["rk4"]["status"] == "skipped" and "dopri5 about" in rows["rk4"]["note"]
    assert rows["rk4"]["judged_by"] and rows["dopri5"]["growth"] == rows["rk4"]["growth"]
    assert result.info["method"] == "dopri5"


def test_a02_says_that_its_flat_positions_make_the_estimate_no_promise(runs):
    """Past A02's flat positions runs at different steps take other branches, 1e-4 m
    apart (benchmarks/a02_convergence.py), which no estimate from two runs sees: the
    run says so, with what it measured."""
    result, texts, _ = runs("a02", 1e-3)
    found = result.info["accuracy"]["singular_approach"]
    # the pilot's outputs every 0.05 s pass within 0.03 of the start's value
    assert found["smallest"] < 0.1 * found["start"] and 0.72 <= found["time"] <= 2.0
    [text] = [t for t in texts if "comes near singular positions" in t]
    assert "not a promise" in text and f"{found['smallest']:.2g}" in text


def test_the_pilot_measures_rk4_where_its_choice_lies(runs):
    """A02's first 0.6 s at 1e-6: the pilot records every 0.05 / 9 s, which holds rk4's
    pair to 5.6 and 2.8 ms where the run can take 25 ms. The pair places the choice
    above it, so the third rung doubles the coarse step (recording on every other
    output time) rather than halving the fine one, and the choice may go to four times
    that rung (choice.EXTRAPOLATION)."""
    result, _, _ = runs("a02s", 1e-6)
    rows = {c["method"]: c for c in result.info["accuracy"]["candidates"]}
    sample = 0.05 / 9
    assert [r[0] for r in rows["rk4"]["rungs"]] == pytest.approx(
        [2 * sample, sample, sample / 2])
    assert result.info["method"] == "rk4" and result.info["dt"] > 4 * sample


def test_a_fixed_step_pair_may_step_a_multiple_of_the_output_interval(runs):
    """The solar array records every 10 ms and its pilot's piece (0.3 s) holds 30 of
    those: rk4's pair steps 20 and 10 ms (the coarse one still records 15 times in the
    piece, enough for the growth) rather than 10 and 5, where dopri5's pilot steps
    25 ms. At 20 ms dopri5's finest rung judges it, and rk4 stops there: it cannot be
    the cheapest."""
    result, _, _ = runs("solar", 1e-6)
    rows = {c["method"]: c for c in result.info["accuracy"]["candidates"]}
    assert [r[0] for r in rows["rk4"]["rungs"]] == pytest.approx([0.02])
    assert rows["rk4"]["status"] == "skipped" and rows["rk4"]["judged_by"]


def test_a_repeat_that_fails_leaves_the_first_run_and_says_why(solvers, monkeypatch):
    """A repeat can fail where the first run did not (A02 over 20 s at 1e-6: dopri5 at
    rtol 1e-13 underflows its step at the first flat position). The first run is
    finished work: it stays the result, and its warning says that the repeat failed
    and why (forced here on Andrews' repeat at 1e-6)."""
    from fccgen.target_error import run as target_run
    real = target_run._attempt
    why = "DOPRI5 step size underflow (forced)"

    def attempt(solver, frame, choice, progress, reactions, twin=None):
        if "repeated" in choice.reason:
            raise SimulationError(why)
        return real(solver, frame, choice, progress, reactions, twin=twin)

    monkeypatch.setattr(target_run, "_attempt", attempt)
    case = refs.CASES["andrews"]
    result, texts = run_to(solvers("andrews"), 1e-6, t_end=case.t_end,
                           output_dt=case.output_dt)
    acc = result.info["accuracy"]
    assert acc["repeated"] is None and acc["repeat_failed"]["error"] == why
    assert acc["method"] == "dopri5" and acc["repeat_failed"]["value"] < acc["value"]
    assert result.info["error_estimate"] > 1e-6
    [text] = [t for t in texts if "exceeds the target" in t]
    assert f"failed ({why})" in text and "the result is the first run" in text
    assert "would reach" not in text
    # the first run's own twin is its estimate; nothing of the failed repeat is counted
    cost = acc["cost"]
    assert cost["repeat"] == 0 and cost["estimate"] > 0
    assert cost["whole"] == cost["pilot"] + cost["run"] + cost["estimate"]
