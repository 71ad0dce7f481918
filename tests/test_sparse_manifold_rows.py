"""Rows dependent only on the constraint manifold on the sparse path
(engine fcc_al_refine.c, "Directions beyond the decided rank"): a linkage mobile by its
geometry (Bricard's loop) has a row that is dependent on the constraints and independent
a little off them, where an RK stage's positions are. Enforcing it there gave stage
accelerations wrong by O(1) that passed every residual test: Bricard in its distance
encoding, forced onto the sparse path, ended 1 s of RK4 0.37 m away from the dense
path's run with 2.2 J more energy. The solver now tells such rows from exactly
dependent ones at the rank decision, and a solve that reaches them is redone densely."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import bricard
import fccgen
from fccgen.cli import _dof_summary
from fccgen.errors import RunWarning
from fccgen.runtime import CompiledSolver


def _sparse(solver):
    return CompiledSolver(solver.plan, solver.module, linear_solver="sparse")


@pytest.mark.parametrize("name, geometric", [
    ("bricard", True), ("deployable", True), ("deployable_joints", True),
    ("a02_n_four_bar", False), ("four_bar", False)])
def test_rows_dependent_only_on_the_constraints_are_told_from_exact_ones(
        compiled, name, geometric):
    """Bricard's and the deployable structure's dependent rows become independent off
    the constraints (rank 23 -> 24, 8 -> 9), A02's planar rows and the four-bar's stay
    dependent (their rows are differences of others everywhere): only the first kind
    turns on the stop, at a Rayleigh quotient far below the kept directions'."""
    solver = _sparse(compiled(name))
    decision = solver.decide_rank(solver.initial_state().q)
    quotient = solver._engine.beyond_rank_quotient
    if geometric:
        kept = decision.gap[0]
        t = 1e7 * (1e-2 * kept) ** 2
        assert 0.0 < quotient == pytest.approx(t / (1.0 + t), rel=1e-12)
    else:
        assert quotient == 0.0


@pytest.mark.parametrize("encoding, stops", [("distance", False), ("line", True)])
def test_bricard_on_the_sparse_path_follows_the_dense_path(tmp_path, build_dir, encoding,
                                                          stops):
    """1 s of the default RK4 (dt 1 ms): P3 within 1e-8 m of the dense path's run
    (measured 1.1e-9 on both encodings; RK4's own error here is ~2e-7 m) and the energy
    kept to 1e-6 J (measured 1.8e-8 and 2.9e-7 J of 29.4 J). Before the stop, the
    distance encoding ended 0.37 m away with 2.2 J more. Solves that reach the row
    beyond the rank are counted, redone densely and warned about: the line encoding's
    do (2096 of 5011). The distance encoding's acceleration solves, started from the
    last accelerations' multipliers (fcc_al_refine.c, "Warm start"), converge in two
    steps without reaching it: none is redone and nothing is warned."""
    path = tmp_path / f"bricard_{encoding}.yaml"
    path.write_text(bricard.text(encoding))
    dense = fccgen.load(path, build_dir, linear_solver="dense")
    sparse = fccgen.load(path, build_dir, linear_solver="sparse")
    rd = dense.simulate(t_end=1.0, output_dt=0.05)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RunWarning)
        rs = sparse.simulate(t_end=1.0, output_dt=0.05)
    redone = [w for w in caught if "reached a row dependent only on the constraints"
              in str(w.message) and "the dense solve redid each of them" in str(w.message)]
    p3 = ["P3.x", "P3.y", "P3.z"]
    assert np.ptp(rs["P3.x"]) > 0.5                      # it moves: 0.73 m in 1 s
    assert max(np.max(np.abs(rs[c] - rd[c])) for c in p3) < 1e-8
    e = rs["energy"]
    assert np.max(np.abs(e - e[0])) < 1e-6
    stats = sparse._engine.solve_statistics()
    assert rs.info["sparse_beyond_rank_solves"] == stats["beyond_rank_stops"]
    assert rs.info["sparse_dense_fallbacks"] == stats["unconverged"]
    assert (stats["beyond_rank_stops"] > 0) == stops == bool(redone)
    assert ("at a row dependent only on the constraints" in _dof_summary(rs.info)) == stops


def test_models_with_rows_dependent_exactly_never_stop_there(compiled):
    """A02 passes its flat position at t = 0.75 s within this 1 s run; its dependent
    rows are exact, so no correction stops beyond the rank and every solve converges."""
    solver = _sparse(compiled("a02_n_four_bar"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        solver.simulate(t_end=1.0, dt=1e-3, reactions=False)
    stats = solver._engine.solve_statistics()
    assert stats["beyond_rank_stops"] == 0 and stats["unconverged"] == 0
