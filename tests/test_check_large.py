"""``fccgen check`` of a model above fccgen.rank.sparse.DENSE_COMPONENT coordinates: a
connected component at a time, from the sparse B, the redundant rows from a certified LU
(fccgen.diagnostics.check, fccgen.rank_rows.independent_rows)."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from fccgen import rank as rank_rule
from fccgen.rank import rows as rank_rows
from fccgen.rank import sparse as rank_sparse
from fccgen.api import load_numeric
from fccgen.diagnostics.check import check_model
from fccgen.mechanism.report import dependency_text

from conftest import example_module


def _mast(bays: int) -> str:
    return example_module("make_scissor_mast").model_text(bays)


def _dense_rank(B) -> int:
    """fccgen.rank's rule on all the singular values of B (rows scaled)."""
    return rank_rule.dense_decision(rank_rule.scaled_singular_values(B), B.shape[1]).rank


def test_check_of_a_33_bay_mast_counts_as_the_run_decides(tmp_path):
    """198 bars, 612 coordinates, 1005 rows: the report's rank, degrees of freedom and
    number of redundant rows are the run's decision, and the rows it names are
    exactly redundant (the others have full rank: the dense SVD of them)."""
    path = tmp_path / "mast_33.yaml"
    path.write_text(_mast(33))
    events = []
    report = check_model(path, progress=events.append)
    solver = load_numeric(path)
    init = solver.initial_state()
    decision = solver.decide_rank(init.q)
    assert solver.n_q > rank_sparse.DENSE_COMPONENT
    assert isinstance(decision, rank_sparse.PartialRankDecision)
    assert (report.n_q, report.n_g) == (612, 1005)
    assert report.rank == decision.rank == 611 and report.dof == decision.dof == 1
    assert len(report.redundant) == report.n_g - decision.rank == 394
    assert report.uncertain == [] and report.rank_gap == decision.gap
    B = solver.constraint_jacobian(init.q)
    named = set(report.redundant)
    kept = [k for k, label in enumerate(report.rows) if label not in named]
    assert len(kept) == decision.rank and len(set(report.rows)) == len(report.rows)
    assert _dense_rank(B[kept]) == len(kept) == _dense_rank(B)
    # the rows taking part in dependencies: from rank_rows.dependency_weights, the
    # same rows as the small models' SVD of all the rows (weights 0.2 and more against
    # 1e-15 and less: the rule's 1e-6 is far from both)
    assert report.dependent == dependency_text(B, decision.rank, report.rows)
    assert report.dependent.startswith("joints XAB0, base_A, XAB1")
    assert "not named" not in report.text()
    assert {e.stage for e in events} == {"check"} and len(events) >= 3


def test_the_lu_choice_of_independent_rows_is_a_basis_of_the_rows():
    """Rows w_i e_i - w_(i+1) e_(i+1) of 600 coordinates (weights w between 0.5 and
    1.5) and 50 sums of neighbouring ones: 599 independent rows chosen, the 50 left
    over depend on them."""
    n = 600
    weights = 1.0 + 0.5 * np.sin(np.arange(n))
    chain = (np.eye(n - 1, n) - np.eye(n - 1, n, k=1)) * weights
    B = np.vstack([chain[:50] + chain[1:51], chain])     # the dependent rows first
    C = rank_sparse.scaled(sp.csr_matrix(B))
    rows = rank_rows.independent_rows(C, n - 1)
    assert rows is not None and rows.size == n - 1
    assert _dense_rank(B[rows]) == n - 1
    # a rank the rows do not have is refused, not forced
    assert rank_rows.independent_rows(C, n - 2) is None


def test_the_sparse_velocity_projection_is_the_dense_one(tmp_path):
    """Random speeds projected at the 33-bay mast's initial state by the sparse KKT
    solve (what a large model takes) and by the dense solve of small models."""
    from fccgen.numeric import sparse_projection
    from fccgen.numeric.constrained import constrained_solve
    path = tmp_path / "mast_33.yaml"
    path.write_text(_mast(33))
    solver = load_numeric(path)
    q = solver.initial_state().q
    v = np.random.default_rng(3).standard_normal(solver.n_q)
    sparse = sparse_projection.project_velocities(solver, q, v, np.zeros(solver.n_g),
                                                  solver.decide_rank(q).rank)
    assert sparse is not None                            # certified: not the fallback
    assert np.array_equal(solver.project_velocities(q, v), sparse)
    M, B = solver.mass_matrix(q), solver.constraint_jacobian(q)
    # the sparse assembly is the dense one (repeats summed in another order: rounding)
    assert np.max(np.abs(solver.constraint_jacobian_sparse(q).toarray() - B)) <= \
        1e-15 * np.max(np.abs(B))
    dense = constrained_solve(M, B, M @ v, np.zeros(solver.n_g), solver.rank_tol)
    scale = np.max(np.abs(dense))
    # measured 5e-13: the condition of the KKT matrix (sigma_r / sigma_1 = 3.6e-4,
    # squared through M) times eps, after refinement; 1e-10 leaves a margin of 200
    assert np.max(np.abs(sparse - dense)) <= 1e-10 * scale
    assert np.max(np.abs(B @ sparse)) <= 1e-13 * scale      # measured 7e-16
    assert np.max(np.abs(sparse)) > 1e-3 * np.max(np.abs(v))  # the motion is kept


def test_components_large_and_small_are_reported_as_the_whole_would_be():
    """A 600-coordinate chain with 50 redundant sums and a 2-coordinate component with
    one doubled row, a zero stored across the two: the redundant rows are a complement of a basis (the kept rows have
    full rank), 51 of them, and the rows taking part in the dependencies are those of
    the SVD of the whole."""
    from fccgen.diagnostics.check import _large_rows
    from fccgen.mechanism.report import dependent_rows
    n = 600
    weights = 1.0 + 0.5 * np.sin(np.arange(n))
    chain = (np.eye(n - 1, n) - np.eye(n - 1, n, k=1)) * weights
    small = np.array([[1.0, 1.0], [2.0, 2.0]])
    B = sp.block_diag([sp.csr_matrix(np.vstack([chain, chain[:50] + chain[1:51]])),
                       small]).tocoo()
    # a stored zero of the last row in the chain's first column (element blocks store
    # the zeros of planar elements): it must not join the two components
    B = sp.coo_matrix((np.append(B.data, 0.0), (np.append(B.row, B.shape[0] - 1),
                                                np.append(B.col, 0))), shape=B.shape)
    B = B.tocsr()
    assert np.any(B.data == 0.0)
    dense = B.toarray()
    rank = _dense_rank(dense)
    labels = [f"bodies.r{k} (length)" for k in range(B.shape[0])]
    notes = []
    redundant, dependent = _large_rows(B, labels, rank, None, notes, lambda *a, **k: None)
    assert rank == n - 1 + 1 and len(redundant) == B.shape[0] - rank == 51
    kept = [k for k, label in enumerate(labels) if label not in set(redundant)]
    assert _dense_rank(dense[kept]) == len(kept) == rank
    expected = [labels[k] for k in dependent_rows(dense, rank)]
    assert dependent == "other rows " + ", ".join(expected) and notes == []
    assert len(expected) == 50 + 51 + 2      # the sums, the rows they add, both doubled


def test_the_command_line_shows_the_steps_of_a_large_check(tmp_path, capsys):
    """stderr not a terminal: one line per step ("fccgen: check: ..."), the report on
    stdout."""
    from fccgen.cli import main
    path = tmp_path / "mast_17.yaml"
    path.write_text(_mast(17))                       # 102 bars, 324 x 525: still small
    assert main(["check", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "coordinates 324" in out and err == ""    # small: no progress lines
    path = tmp_path / "mast_33.yaml"
    path.write_text(_mast(33))
    assert main(["check", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "coordinates 612, constraint equations 1005, rank 611" in out
    assert "redundant constraint equations: 394" in out
    assert "fccgen: check: rank decision" in err
    assert "fccgen: check: rows taking part in the dependencies (394" in err
