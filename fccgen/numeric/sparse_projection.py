"""The velocity projection of a large model with sparse matrices (the dense solve,
numeric/constrained.py, costs O(n^3): 40 s at 3024 coordinates).

    v = argmin (v - v_t)^T M (v - v_t) / 2   subject to   B v = b

B has redundant rows; with S a basis of its rows (fccgen.rank_rows.independent_rows,
certified by the rank decision) the rows outside S are combinations of S, so B v = b
is B_S v = b_S (b consistent, as dg/dt of consistent drivers is), and with B_S of full
row rank and M positive definite on its null space the KKT matrix

    [ M    B_S^T ] [ v ]   [ M v_t ]
    [ B_S  0     ] [ l ] = [ b_S   ]

is nonsingular: one sparse LU (SuperLU) and two steps of iterative refinement (rows of
B_S scaled as in the dense solve; the scissor mast's sigma_r / sigma_1 ~ 1e-5 makes the
matrix ill-conditioned, which refinement pays for). Anything that cannot be certified
(no basis of the decided rank: the rank changed; a singular factor) returns None, and
the caller takes the dense solve, which keeps the rank statistics and says what is
wrong.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..rank import rows as rank_rows
from ..rank import scales_from_norms

REFINEMENTS = 2          # steps of iterative refinement of the KKT solve


def sparse_jacobian(solver, q):
    """B at q as CSR from the element blocks (a coordinate shared by rows of one
    element repeats: the COO sum adds the repeats, as the dense assembly does)."""
    rows, cols, values = [], [], []
    for _, idx, r, k in solver._kernels(q, None):
        block = k.evaluate("constraint_jacobian")
        if block is None or not len(r):
            continue
        rows.append(np.repeat(r, len(idx)))
        cols.append(np.tile(idx, len(r)))
        values.append(np.asarray(block, float).ravel())
    shape = (solver.n_g, solver.n_q)
    if not rows:
        return sp.csr_matrix(shape)
    B = sp.coo_matrix((np.concatenate(values), (np.concatenate(rows),
                                                 np.concatenate(cols))), shape=shape).tocsr()
    B.eliminate_zeros()               # the zeros of the blocks (planar elements, ...)
    return B


def sparse_square(solver, q, v, name: str):
    """The n_q x n_q kernel ``name`` (mass_matrix, ...) as CSR from the element blocks."""
    rows, cols, values = [], [], []
    for _, idx, _, k in solver._kernels(q, v):
        block = k.evaluate(name)
        if block is None:
            continue
        rows.append(np.repeat(idx, len(idx)))
        cols.append(np.tile(idx, len(idx)))
        values.append(np.asarray(block, float).ravel())
    n = solver.n_q
    if not rows:
        return sp.csr_matrix((n, n))
    return sp.coo_matrix((np.concatenate(values), (np.concatenate(rows),
                                                    np.concatenate(cols))),
                         shape=(n, n)).tocsr()


def project_velocities(solver, q, v, b, rank: int) -> np.ndarray | None:
    """The projection of the module docstring at q of the speeds v onto B v = b, with
    the decided ``rank`` of B; None when it cannot be certified."""
    M = sparse_square(solver, q, None, "mass_matrix")
    return constrained_step(solver, q, M, M @ np.asarray(v, float), b, rank)


def constrained_step(solver, q, M, Q, b, rank: int) -> np.ndarray | None:
    """x minimising x^T M x / 2 - Q^T x subject to B(q) x = b (the KKT solve of the
    module docstring; M sparse), with ``rank`` the rank of B(q); None when it cannot be
    certified."""
    B = solver.constraint_jacobian_sparse(q)
    norms = np.sqrt(np.asarray(B.multiply(B).sum(axis=1)).ravel())
    scale = scales_from_norms(norms, solver.row_groups)
    C = (sp.diags(1.0 / scale) @ B).tocsr()
    keep = rank_rows.independent_rows(C, rank) if rank > 0 else np.zeros(0, int)
    if keep is None or not np.all(np.isfinite(C.data)):
        return None
    CS = C[keep]
    K = sp.bmat([[M, CS.T], [CS, None]], format="csc")
    rhs = np.concatenate([Q, np.asarray(b, float)[keep] / scale[keep]])
    try:
        lu = splu(K)
    except RuntimeError:                  # exactly singular: the dense solve says why
        return None
    x = lu.solve(rhs)
    for _ in range(REFINEMENTS):
        x = x + lu.solve(rhs - K @ x)
    if not np.all(np.isfinite(x)):
        return None
    return x[:solver.n_q]
