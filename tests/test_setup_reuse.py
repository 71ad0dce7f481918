"""A run's set-up kept per start (fccgen.runtime.setup_reuse): reusing it never changes
an answer, a changed start, or a solver of other numbers, decides afresh, and
``result.info["setup"]`` says which phases were reused."""
from __future__ import annotations

import numpy as np

from fccgen import rank as rank_rule
from fccgen.runtime import setup_reuse


def _fresh(compiled, name="four_bar"):
    """A solver of the example's compiled module with nothing kept yet (neither its
    own set-ups nor the decisions kept for every solver of the process)."""
    setup_reuse.forget()
    return compiled(name).with_parameters({})


def _same(a, b) -> None:
    np.testing.assert_array_equal(a.t, b.t)
    assert a.columns.keys() == b.columns.keys()
    for name, column in a.columns.items():
        np.testing.assert_array_equal(column, b.columns[name], err_msg=name)


def test_a_second_run_reuses_the_setup_bit_for_bit(compiled):
    solver = _fresh(compiled)
    first = solver.simulate(t_end=0.05, dt=1e-3)
    second = solver.simulate(t_end=0.05, dt=1e-3)
    assert first.info["setup"]["rank_decision"]["reused"] is False
    assert first.info["setup"]["initial_state"]["reused"] is False
    assert second.info["setup"]["rank_decision"]["reused"] is True
    assert second.info["setup"]["initial_state"]["reused"] is True
    assert second.info["setup"]["seconds"] >= 0.0
    _same(first, second)
    for key in ("rank", "dof", "rank_gap", "final_dof"):
        assert first.info[key] == second.info[key]
    _same(second, _fresh(compiled).simulate(t_end=0.05, dt=1e-3))


def test_a_changed_start_decides_afresh(compiled, monkeypatch):
    solver = _fresh(compiled)
    run = solver.simulate(t_end=0.3, dt=1e-3)
    names = [name for name, _ in solver.plan.triples]
    q = np.array([run.columns[f"{t}.{c}"][-1] for t in names for c in "xyz"])
    v = np.array([run.columns[f"{t}.v{c}"][-1] for t in names for c in "xyz"])
    calls = []
    decide = rank_rule.decide
    monkeypatch.setattr(rank_rule, "decide", lambda *a, **k: calls.append(1) or decide(*a, **k))
    moved = solver.simulate(t_end=0.05, dt=1e-3, q0=q, v0=v)
    assert moved.info["setup"]["rank_decision"]["reused"] is False and calls
    again = solver.simulate(t_end=0.05, dt=1e-3, q0=q, v0=v)
    assert again.info["setup"]["rank_decision"]["reused"] is True
    fresh = _fresh(compiled).simulate(t_end=0.05, dt=1e-3, q0=q, v0=v)
    _same(moved, again)
    _same(moved, fresh)
    assert moved.info["rank_gap"] == fresh.info["rank_gap"]


def test_other_numbers_or_tolerances_key_other_setups(compiled):
    solver = _fresh(compiled)
    q = np.asarray(solver.plan.q0, float)
    heavier = solver.with_parameters({"bodies.crank.mass": 2.0})
    assert solver.setup_store.key("rank", q) != heavier.setup_store.key("rank", q)
    assert solver.setup_store.key("rank", q) != solver.setup_store.key("rank", q + 1e-15)
    assert solver.setup_store.key("rank", q) == _fresh(compiled).setup_store.key("rank", q)


def test_a_kept_initial_state_leaves_the_solver_at_t_0(compiled):
    """As a fresh one does: a driven model's projections after it are at t = 0 (equal
    to a fresh solver's to 1e-12 m, the Newton projection's tolerance being 1e-11 of
    the length; at t = 0.7 the driver has moved the mechanism by about 0.1 m)."""
    solver = _fresh(compiled, "four_bar_driven")
    fresh = solver.initial_state()
    moved = fresh.q + 1e-6
    solver.set_time(0.7)
    later = solver.project_positions(moved)[0]
    kept = solver.initial_state()
    np.testing.assert_array_equal(kept.q, fresh.q)
    at_zero = _fresh(compiled, "four_bar_driven").project_positions(moved)[0]
    np.testing.assert_allclose(solver.project_positions(moved)[0], at_zero, rtol=0,
                               atol=1e-12)
    assert np.max(np.abs(later - at_zero)) > 1e-3


def test_a_solver_of_other_masses_sets_up_without_an_svd(compiled, monkeypatch):
    """The small-model path choice (paths.reduced_mass_spread: B's null space) and the
    rank-growth watch's start basis (the sparse engine of a model with events) are
    functions of B alone, kept per process like the rank decisions: a solver of other
    masses at the same start, as a sensitivity's shifted models, simulate_many and a
    sweep make them, takes them without an SVD, and its run equals a fresh one bit for
    bit."""
    for name, body in (("four_bar", "coupler"), ("solar_array", "panel1")):
        solver = _fresh(compiled, name)
        solver.simulate(t_end=0.02, dt=1e-3, reactions=False)
        heavier = solver.with_parameters({f"bodies.{body}.mass": 1.7})
        calls = []
        svd = np.linalg.svd
        monkeypatch.setattr(np.linalg, "svd", lambda *a, **k: calls.append(1) or svd(*a, **k))
        run = heavier.simulate(t_end=0.02, dt=1e-3, reactions=False)   # theirs: an SVD
        monkeypatch.setattr(np.linalg, "svd", svd)
        assert not calls, name
        setup_reuse.forget()
        _same(run, solver.with_parameters({f"bodies.{body}.mass": 1.7}).simulate(
            t_end=0.02, dt=1e-3, reactions=False))
