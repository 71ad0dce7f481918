"""The sparse path near a singular position (engine fcc_al_refine.c, "Near a singular
position"): once a solve's augmented-Lagrangian steps slow down, A is factored again
with the penalties raised FCC_AL_BOOST, so the conjugate-gradient corrections meet
eigenvalues t / (1 + t) with t that much larger and take a few steps, not a hundred;
the next factorisations are made with the raised penalties at once while the solves
stay slow; the answers stay the dense path's."""
from __future__ import annotations

import numpy as np

from fccgen.runtime import CompiledSolver


def _state(solver, result):
    """(q, v) of a run's last row."""
    q = [result[f"{name}.{c}"][-1] for name, _ in solver.plan.triples for c in "xyz"]
    v = [result[f"{name}.v{c}"][-1] for name, _ in solver.plan.triples for c in "xyz"]
    return np.array(q), np.array(v)


def test_solves_through_the_a02_flat_position_stay_short_and_agree_with_dense(compiled):
    """A02 (N = 40) through its flat position at t = 1.24 s (rockers horizontal):
    80 ms of RK4 from t = 1.2 s. Without the raised penalty a solve there took up to
    59 iterations; with it at most 30 (measured 11; 19 when each raise waited for a
    solve with RHO to turn slow), some factorisations raised, every solve converged.
    The raised factorisations replace factorisations with RHO instead of following
    them: fewer than the 4 per RK4 step (3 stages and the velocity projection) are made
    with RHO (measured 275 of 320; 322 when each raise followed one with RHO). The run
    agrees with the dense path's to 1e-9 of each column (tests/test_sparse_path.py's
    bound for one-second runs; measured 5.1e-12, 2.0e-12 without the raised penalty:
    A's rounding, 1e5 times larger, left in the refinement's last digits)."""
    shared = compiled("a02_n_four_bar")
    sparse = CompiledSolver(shared.plan, shared.module, linear_solver="sparse")
    dense = CompiledSolver(shared.plan, shared.module, linear_solver="dense")
    q, v = _state(sparse, sparse.simulate(t_end=1.2, dt=1e-3))
    run = sparse.simulate(t_end=0.08, dt=1e-3, q0=q, v0=v)
    stats = sparse._engine.solve_statistics()
    assert stats["unconverged"] == 0 and run.info["sparse_unconverged_solves"] == 0
    assert stats["boosted_factorisations"] > 0
    assert stats["max_iterations"] <= 30, stats
    assert stats["factorisations"] - stats["boosted_factorisations"] < 4 * 80, stats
    reference = dense.simulate(t_end=0.08, dt=1e-3, q0=q, v0=v)
    for column in reference.columns:
        scale = max(1.0, float(np.max(np.abs(reference[column]))))
        assert np.max(np.abs(run[column] - reference[column])) <= 1e-9 * scale, column
