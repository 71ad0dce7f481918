"""The sparse path's refinement on ill-conditioned constraints (engine fcc_al_refine.c):
it converges near the A02 chain's flat position, agrees with the dense path there, and
a solve that does not converge is redone densely or kept, but never silently: the run
counts it, warns, and the command line's summary says it."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import example_module
from fccgen.cli import _dof_summary
from fccgen.errors import RunWarning
from fccgen.runtime import CompiledSolver
from fccgen.runtime._sparse import SparseEngine


def _chain_text(n: int) -> str:
    return example_module("make_n_four_bar").model_text(n)


def _state(solver, result):
    """(q, v) of a run's last row."""
    q = [result[f"{name}.{c}"][-1] for name, _ in solver.plan.triples for c in "xyz"]
    v = [result[f"{name}.v{c}"][-1] for name, _ in solver.plan.triples for c in "xyz"]
    return np.array(q), np.array(v)


def _largest_difference(a, b) -> float:
    """Largest difference of two runs' columns, each relative to max(1, its size)."""
    return max(float(np.max(np.abs(a[c] - b[c])) / max(1.0, np.max(np.abs(b[c]))))
               for c in b.columns)


def test_the_a02_chain_of_80_loops_converges_near_its_flat_position(tmp_path, build_dir):
    """A02 with N = 80 loops (243 coordinates) approaches its flat position at
    t = 1.245 s, where 80 singular values of B fall to 1e-7..1e-9 of the largest: every
    sparse solve up to t = 1.244 converges (before the conjugate gradients stopped on
    the residual, 38 did not), and from t = 1.2 both paths take the same steps."""
    import fccgen
    path = tmp_path / "a02_80.yaml"
    path.write_text(_chain_text(80))
    solver = fccgen.load(path, build_dir)
    assert isinstance(solver._engine, SparseEngine)
    head = solver.simulate(t_end=1.2, dt=1e-3)
    assert head.info["sparse_unconverged_solves"] == 0 and head.info["sparse_solves"] > 0
    q, v = _state(solver, head)
    dense = CompiledSolver(solver.plan, solver.module, linear_solver="dense")
    tail_sparse = solver.simulate(t_end=0.044, dt=1e-3, q0=q, v0=v)
    tail_dense = dense.simulate(t_end=0.044, dt=1e-3, q0=q, v0=v)
    assert tail_sparse.info["sparse_unconverged_solves"] == 0
    assert solver._engine.solve_statistics()["max_iterations"] <= 400
    # 1e-8: near the flat position an acceleration is determined to about
    # eps / sigma_min of B (3e-8 at t = 1.245: the dense solve against an SVD
    # reference); measured 1.5e-10 between the paths at t = 1.244.
    assert _largest_difference(tail_sparse, tail_dense) < 1e-8


def _forced(compiled, fallback_max=None):
    """A02 (N = 40) on its own sparse solver whose solves stop after one
    augmented-Lagrangian step and one correction: none converges."""
    shared = compiled("a02_n_four_bar")
    solver = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    solver._engine.limit_refinement(corrections=1, cg_steps=0, al_steps=1)
    if fallback_max is not None:
        solver._engine.set_dense_fallback_max(fallback_max)
    return solver


def test_an_unconverged_sparse_solve_is_redone_densely_and_reported(compiled):
    solver = _forced(compiled)
    with pytest.warns(RunWarning, match=r"did not converge.*the dense solve redid each"):
        result = solver.simulate(t_end=0.01, dt=1e-3)
    info = result.info
    assert info["sparse_unconverged_solves"] > 0
    assert info["sparse_dense_fallbacks"] == info["sparse_unconverged_solves"]
    assert info["sparse_solves"] >= info["sparse_unconverged_solves"]
    assert "sparse solves did not converge" in _dof_summary(info)
    # the fallback is the dense path's solve: the runs agree as the paths do
    # (1e-9, tests/test_sparse_path.py's one-second runs)
    dense = CompiledSolver(solver.plan, solver.module, linear_solver="dense")
    assert _largest_difference(result, dense.simulate(t_end=0.01, dt=1e-3)) < 1e-9


def test_an_unconverged_sparse_solve_kept_says_what_to_change(compiled):
    solver = _forced(compiled, fallback_max=0)
    with pytest.warns(RunWarning, match=r"kept as they were.*--linear-solver dense"):
        result = solver.simulate(t_end=0.005, dt=1e-3)
    assert result.info["sparse_unconverged_solves"] > 0
    assert result.info["sparse_dense_fallbacks"] == 0


def test_converged_sparse_runs_report_no_unconverged_solve(compiled):
    result = compiled("a02_n_four_bar").simulate(t_end=0.01, dt=1e-3)
    assert result.info["sparse_unconverged_solves"] == 0
    assert result.info["singular_position_factorisations"] == 0
    assert "sparse solves" not in _dof_summary(result.info)
    with pytest.raises(ValueError, match="at least one correction"):
        _forced(compiled)._engine.limit_refinement(corrections=0)


def test_warm_started_acceleration_solves_take_two_steps(compiled):
    """The accelerations start from the last accelerations' multipliers
    (fcc_al_refine.c, "Warm start"): over 0.2 s of A02's RK4 the solves, every step's
    velocity projection included, average at most 2.2 solves with A (measured 2.0;
    from zero multipliers the cart of 20 links averaged 3.5). The runs' agreement
    with the dense path is tests/test_sparse_path.py's."""
    shared = compiled("a02_n_four_bar")
    solver = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    init = solver.initial_state()
    solver.simulate(t_end=0.2, dt=1e-3, output_dt=0.05, reactions=False,
                    q0=init.q, v0=init.v)
    stats = solver._engine.solve_statistics()
    assert stats["unconverged"] == 0
    assert stats["iterations"] <= 2.2 * stats["solves"], stats


def test_direct_acceleration_calls_do_not_depend_on_earlier_calls(compiled):
    """Every direct call starts from zero multipliers: the same state gives the same
    bits whatever was solved before (runs do the same at their start)."""
    shared = compiled("a02_n_four_bar")
    solver = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    init = solver.initial_state()
    first = solver.accelerations(init.q, init.v)
    solver.accelerations(init.q, 2.0 * init.v)
    assert np.array_equal(solver.accelerations(init.q, init.v), first)


def test_newton_steps_stop_sooner_and_land_where_the_dense_ones_do(compiled):
    """A Newton step's solve stops at NEWTON_STOP (fcc_al_refine.c): two solves with A
    where the accelerations' tolerance took three. Positions 1e-4 m off A02's
    constraints in their plane (z stays: the sparse pattern is the plane's) take two
    Newton steps on both paths and land on the same point to 1e-13 m, 14 units in the
    last place of coordinates of up to 40 m (measured 7.1e-15 m, one unit): each
    step's error is about 1e-14 of the step."""
    shared = compiled("a02_n_four_bar")
    sparse = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    dense = CompiledSolver(shared.plan, shared.module, linear_solver="dense")
    init = sparse.initial_state()
    dense.decide_rank(init.q)
    kick = 1e-4 * np.random.default_rng(7).standard_normal(sparse.n_q)
    kick[2::3] = 0.0
    q = init.q + kick
    before = sparse._engine.solve_statistics()
    qs, its, converged, residual = sparse._engine.project_positions(q)
    after = sparse._engine.solve_statistics()
    qd, itd, _, _ = dense._engine.project_positions(q)
    assert converged and its == itd == 2 and residual <= sparse.position_tol
    assert after["solves"] - before["solves"] == its
    assert after["iterations"] - before["iterations"] == 2 * its
    assert np.max(np.abs(init.q)) <= 40.0
    assert np.max(np.abs(qs - qd)) < 1e-13


def test_the_projection_after_a_step_takes_chord_steps(compiled):
    """After an RK4 step the position projection's Newton steps are chord steps with
    the last stage's M, B and factorisation (engine fcc_sparse_engine.c, "Chord steps"): over
    0.5 s of the four-bar every Newton step is one and none is undone, so a step makes
    four factorisations (the velocity projection's serves the next first stage) and
    max |g| stays within the tolerance. The runs' agreement with the dense path is
    tests/test_sparse_path.py's."""
    shared = compiled("four_bar")
    solver = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    init = solver.initial_state()
    result = solver.simulate(t_end=0.5, dt=1e-3, output_dt=0.1, reactions=False,
                             q0=init.q, v0=init.v)
    stats = solver._engine.rank_statistics()
    assert result.info["newton_iterations"] > 50
    assert stats["chord_steps"] == result.info["newton_iterations"]
    assert stats["chord_steps_undone"] == 0
    assert stats["factorisations"] == 4 * result.info["steps"] + 1
    assert result.info["max_constraint_error"] <= solver.position_tol * 10


def test_chord_steps_are_kept_only_where_they_match_the_exact_ones(compiled):
    """With a factorisation made 1e-6 m from q (as after an RK4 step), a chord step
    from 1e-10 m off the constraints is kept and lands within 1e-14 m of the exact
    projection (its move along the constraints is about the step times the relative
    change d of B, 1e-5); from 1e-7 m off, the same move (measured 1.7e-12 m) would
    pass CHORD_DRIFT of the tolerance, so it is undone; with a factorisation made at a
    position of the loop about 0.05 m away, the step leaves more than CHORD_GAIN of
    the residual and is undone. Undone steps leave exact steps, which give the exact
    projection's point. (B at q with the stage's factorisation would move q by about
    1e7 d times the step.)"""
    shared = compiled("four_bar")
    solver = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    engine = solver._engine
    init = solver.initial_state()
    kick = np.random.default_rng(11).standard_normal(solver.n_q)
    kick[2::3] = 0.0
    zeros_q, zeros_g = np.zeros(solver.n_q), np.zeros(solver.n_g)

    def chord(q, factor_at):
        exact, _, ok, _ = engine.project_positions(q)
        assert ok
        engine.solve_at(factor_at, zeros_q, zeros_g)
        before = engine.rank_statistics()
        got, iterations, ok, _ = engine.project_positions(q, reuse=True)
        after = engine.rank_statistics()
        assert ok and iterations >= 1
        kept = after["chord_steps"] - before["chord_steps"]
        undone = after["chord_steps_undone"] - before["chord_steps_undone"]
        return kept, undone, float(np.max(np.abs(got - exact)))

    q = init.q + 1e-10 * kick
    kept, undone, off = chord(q, q + 1e-6 * kick)
    assert kept >= 1 and undone == 0 and off < 1e-14
    q = init.q + 1e-7 * kick
    kept, undone, off = chord(q, q + 1e-6 * kick)
    assert kept == 0 and undone == 1 and off < 1e-15
    far, _ = solver.project_positions(init.q + 0.05 * kick)   # another position
    kept, undone, off = chord(q, far)
    assert kept == 0 and undone == 1 and off < 1e-15


def test_the_long_scissor_boom_ends_its_raised_solves_at_rounding(tmp_path, build_dir):
    """The planar scissor boom of 250 units (2265 coordinates; sigma_r / sigma_1 ~ N^-2)
    runs on the raised alpha (fcc_al_refine.c, "Near a singular position"). Its warm
    acceleration solves and velocity projections start near rounding; the conjugate
    gradients' bound is then the residual's rounding, not CG_TOL^2 of a rounding-size
    residual. Before, those solves ran all their corrections, counted as not converged
    and were done again with RHO's factor: 46 solves with A in the longest, 12.8 per
    constrained solve over 10 steps; now 6-7 (at most 15 allowed here, 10 on average).
    The run agrees with the dense path's (1e-10 of each column, or of 1: measured 3e-15
    of the speeds after 3 steps)."""
    import fccgen
    path = tmp_path / "boom_250.yaml"
    path.write_text(example_module("make_scissor_boom").model_text(250, latch=False))
    solver = fccgen.load(path, build_dir)
    assert solver.sparse and solver.n_q == 2265
    init = solver.initial_state()
    result = solver.simulate(t_end=0.005, dt=1e-3, q0=init.q, v0=init.v)
    stats = solver._engine.rank_statistics()
    assert result.info["sparse_unconverged_solves"] == 0
    assert stats["sparse_most_iterations"] <= 15
    assert stats["sparse_iterations"] <= 10 * stats["sparse_solves"]
    short = solver.simulate(t_end=0.001, dt=1e-3, q0=init.q, v0=init.v)
    dense = CompiledSolver(solver.plan, solver.module, linear_solver="dense")
    reference = dense.simulate(t_end=0.001, dt=1e-3, q0=init.q, v0=init.v)
    assert _largest_difference(short, reference) <= 1e-10
