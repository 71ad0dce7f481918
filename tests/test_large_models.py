"""Large models: the rank decision without a dense SVD (fccgen.rank.sparse) and a
200-body deployable mast (examples/make_scissor_mast.py) through the large-model path."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from fccgen import rank as rank_rule
from fccgen.rank import rows as rank_rows
from fccgen.rank import sparse as rank_sparse

from conftest import example_module


def _dense_rule(B, groups=None):
    """fccgen.rank's rule on all the singular values (the reference)."""
    return rank_rule.dense_decision(rank_rule.scaled_singular_values(B, groups), B.shape[1])


def _difference_rows(n: int) -> np.ndarray:
    """Rows e_i - e_(i+1): rank n - 1, the constants its null space, smallest nonzero
    singular value 2 sin(pi / 2n) (5.2e-3 of the largest, 2, at n = 600)."""
    return np.eye(n - 1, n) - np.eye(n - 1, n, k=1)


def test_a_large_component_is_decided_as_the_dense_rule_decides():
    n = 600
    chain = _difference_rows(n)
    redundant = chain[:50] + chain[1:51]              # sums of rows: 50 redundant rows
    small = np.array([[1.0, 1.0], [2.0, 2.0]])        # a second component, rank 1
    B = sp.block_diag([sp.csr_matrix(np.vstack([chain, redundant])), small]).toarray()
    decision = rank_rule.decide(B, B.shape[1])
    reference = _dense_rule(B)
    assert n > rank_sparse.DENSE_COMPONENT
    assert isinstance(decision, rank_sparse.PartialRankDecision)
    assert decision.rank == reference.rank == (n - 1) + 1
    assert decision.dof == 2 and decision.uncertain == [] == reference.uncertain
    kept, dropped = decision.gap
    # sigma_r from Lanczos on C^T C: relative error ~ eps ||G|| / sigma_r^2 ~ 1e-11
    assert kept == pytest.approx(reference.gap[0], rel=1e-8)
    # the dropped side is the certified bound ||C X||: below the rule's clear zero
    assert dropped <= rank_rule.AMBIGUOUS_LOW


def test_zero_rows_and_coordinates_without_rows_count_as_the_dense_rule_counts():
    n = 600
    B = np.vstack([_difference_rows(n), np.zeros((2, n))])   # two zero rows at the end
    B[:, 10] = 0.0                  # coordinate 10 in no row: its own component; the
    decision = rank_rule.decide(B, n)   # chain splits into 10 and 589 coordinates, each
    reference = _dense_rule(B)          # held at the cut: all 599 rows independent
    assert isinstance(decision, rank_sparse.PartialRankDecision)
    assert decision.rank == reference.rank == n - 1 and decision.uncertain == []


def test_stored_zeros_do_not_join_components():
    """Two blocks, rows 0-1 on columns 0-1 and row 2 on columns 2-3, with a stored zero
    of row 2 in column 0 placed first (planar elements store such zeros): two
    components, row 2 in the second. Without dropping the zero, the row's first stored
    entry put it in the first."""
    data = np.array([1.0, 2.0, 3.0, 4.0, 0.0, 5.0, 6.0])
    indices = np.array([0, 1, 0, 1, 0, 2, 3])
    C = sp.csr_matrix((data, indices, np.array([0, 2, 4, 7])), shape=(3, 4))
    assert C.nnz == 7                                    # the zero is stored
    parts = sorted((list(r), list(c)) for r, c in rank_sparse.components(C))
    assert parts == [([0, 1], [0, 1]), ([2], [2, 3])]


def test_a_singular_value_in_the_uncertain_band_is_left_to_the_dense_rule():
    n = 600
    chain = _difference_rows(n)
    near = chain[0] + 1e-7 * np.eye(1, n, n - 1)[0]   # nearly repeats row 0
    B = np.vstack([chain, near])
    decision = rank_rule.decide(B, n)
    reference = _dense_rule(B)
    assert not isinstance(decision, rank_sparse.PartialRankDecision)
    assert decision.rank == reference.rank
    assert decision.uncertain, "the near-repeated row lies in the uncertain band"
    # the same singular value, scaled through sparse rows: rounding of order
    # eps sigma_1 / sigma ~ 1e-7 relative at sigma ~ 1e-9
    assert decision.uncertain == pytest.approx(reference.uncertain, rel=1e-6)


@pytest.mark.parametrize("name", ["bricard", "scissor_boom", "rsup"])
def test_the_sparse_jacobian_is_the_dense_one(compiled, name):
    """B from the element blocks (what large models use) equals the dense assembly:
    the same sums of the same kernel outputs, so to the last bit up to the order of
    the additions (1e-15 of the largest entry)."""
    solver = compiled(name)
    q = solver.initial_state().q
    dense = solver.constraint_jacobian(q)
    sparse = solver.constraint_jacobian_sparse(q)
    assert sparse.shape == dense.shape
    assert np.max(np.abs(sparse.toarray() - dense)) <= 1e-15 * np.max(np.abs(dense))


def _mast(bays: int) -> str:
    return example_module("make_scissor_mast").model_text(bays)


def test_a_200_body_mast_loads_through_the_large_model_path(tmp_path, build_dir):
    """33 bays, 198 bars, 612 coordinates, 1005 rows: the sparse path's load-time
    analysis, the initial assembly and the rank decision without a dense SVD; one
    degree of freedom (the mast's deployment); a short run on the sparse path agrees
    with the dense path and keeps the energy."""
    import fccgen
    from fccgen.runtime.solver import CompiledSolver
    path = tmp_path / "mast_33.yaml"
    path.write_text(_mast(33))
    solver = fccgen.load(path, build_dir)
    assert len(solver.plan.bodies) == 198 and solver.sparse
    init = solver.initial_state()
    assert init.position_residual < 1e-12          # the written hubs are consistent
    decision = solver.decide_rank(init.q)
    assert isinstance(decision, rank_sparse.PartialRankDecision)
    assert decision.dof == 1 and decision.uncertain == []
    reference = _dense_rule(solver.constraint_jacobian(init.q), solver.row_groups)
    assert reference.rank == decision.rank and reference.uncertain == []
    # its sparse solve at the start against a reference from the SVD of B (null space
    # N, rank 611): a = a_p + N z with B a_p = -c and N^T (f - h - M a) = 0. 1e-10
    # relative: the reference is exact to ~1e-13 (sigma_r / sigma_1 = 3.6e-4), the
    # sparse solve measured 4e-12 off it; the unconverged solve before the residual test
    # of the conjugate gradients was off by 4.9 times the reference
    q, v = init.q, init.v
    M, B = solver.mass_matrix(q), solver.constraint_jacobian(q)
    rhs = solver.applied_forces(q, v) - solver.h_vector(q, v)
    c = solver.constraint_bias(q, v)
    _, sigma, vt = np.linalg.svd(B)
    rank = int(np.sum(sigma > 1e-9 * sigma[0]))
    null = vt[rank:].T
    a_p = np.linalg.lstsq(B, -c, rcond=1e-9)[0]
    a_ref = a_p + null @ np.linalg.solve(null.T @ M @ null, null.T @ (rhs - M @ a_p))
    a = solver._engine.solve_at(q, rhs, -c)
    assert solver._engine.solve_statistics()["unconverged"] == 0
    assert np.max(np.abs(a - a_ref)) < 1e-10 * np.max(np.abs(a_ref))
    # the sparse path (the default) runs it, and takes the same steps as the dense path
    # from the same decision: 1e-10 of each column (or of 1), the solves' rounding
    # (measured 5e-14 of the positions; before the refinement's conjugate gradients
    # stopped on the residual, its solves did not converge from 17 bays on)
    result = solver.simulate(t_end=0.005, dt=1e-3, q0=init.q, v0=init.v)
    assert result.info["dof"] == 1 and result.info["sparse_unconverged_solves"] == 0
    dense = CompiledSolver(solver.plan, solver.module, linear_solver="dense")
    reference = dense.simulate(t_end=0.005, dt=1e-3, q0=init.q, v0=init.v)
    for column in reference.columns:
        assert np.max(np.abs(result[column] - reference[column])) <= 1e-10 * max(
            1.0, np.max(np.abs(reference[column]))), column
    energy = result["energy"]        # RK4 at dt 1e-3, 5 steps: drift ~1e-13 relative
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * abs(energy[0])
    height = result["A33.z"]         # the springs deploy the mast: the top hub rises
    assert height[-1] > height[0]


def test_smallest_right_vectors_span_the_dense_null_space():
    """The sparse path's rank-growth watch starts, above rank.dense_columns_max()
    coordinates, from rank_sparse.smallest_right_vectors instead of a dense SVD: on a
    600 x 700 chain-like sparse matrix of nullity 103 (700 - 597, three dependent
    rows) asked for the 103 + 2 smallest, its vectors span the dense SVD's: the
    principal angles' sines are below 1e-8 (Lanczos to ~1e-10 relative; the gap to the
    next singular value is O(1)) and the basis is orthonormal to 1e-10."""
    rng = np.random.default_rng(3)
    n, m = 700, 600
    rows, cols = np.repeat(np.arange(m), 3), np.concatenate(
        [np.arange(k, k + 3) for k in range(m)])
    C = sp.csr_matrix((rng.normal(size=3 * m), (rows, cols)), shape=(m, n)).tolil()
    for k in (100, 300, 500):
        C[k] = C[k - 1] + C[k + 1]                    # three rows dependent
    C = C.tocsr()
    _, sigma, vt = np.linalg.svd(C.toarray())
    nullity = n - int(np.sum(sigma > 1e-8 * sigma[0]))
    assert nullity == 103
    X = rank_sparse.smallest_right_vectors(C, nullity)
    want = vt[n - nullity:].T
    assert np.abs(X.T @ X - np.eye(nullity)).max() < 1e-10
    sines = np.linalg.svd(want - X @ (X.T @ want), compute_uv=False)
    assert sines.max() < 1e-8
