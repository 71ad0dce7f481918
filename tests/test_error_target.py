"""simulate(error=E): the error reached, its estimate and the cost of the choice,
against independent references (tests/error_references.py): A01's closed form, A02's
published table, the Lagrange top's Euler-angle equations, and a fine run of the solar
array with its two latches.

What each case must show (docs/accuracy.md):
- the true error is at most E, or at most 3E with the run's own warning;
- the estimate info["error_estimate"] is within 10x of the true error;
- the run costs (in evaluations, deterministic counts) at most 2x the cheapest
  hand-tuned method and setting that meets E (tests/data/error_target_grid.json).
E = 1e-9 runs here for the top and the solar array: A01 over 2000 s at 1e-9 takes
~20 s of CPU (its figures are in docs/accuracy.md, from benchmarks/error_target.py),
and A02's published table has six digits, so it judges the 1e-3 level only.
"""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import error_references as refs
from conftest import ROOT
from fccgen.errors import RunWarning
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
