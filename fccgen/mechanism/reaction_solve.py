"""The minimum-norm least-squares solution x = E^+ b of the reaction balance
(:mod:`fccgen.mechanism.reactions`), record by record.

The rule is the dense one: the singular values of E at or below RANK_RTOL times the
largest are dropped (redundant constraints leave reaction components undetermined;
the minimum-norm x is reported then). Two ways reach it:

* dense (:func:`solve_dense`): the SVD of every record's E, vectorised over records.
  What small systems take (at most DENSE_UNKNOWNS unknowns), and every record that
  the sparse way cannot certify;
* sparse (:func:`solve_sparse`), for one record: E is sparse (6 n_b x unknowns, a
  few entries per column) and G = E^T E is its small sparse Gram matrix. One LDL^T of
  G - tau I (SuperLU in symmetric mode with diagonal pivots; tau = (ZERO_TOL s)^2,
  s^2 = ||G||_1 >= sigma_1^2) gives both the certificate and the solve:

  - the number of its negative pivots is the number of eigenvalues of G below tau
    (Sylvester's law of inertia). None means every sigma_k of E exceeds
    ZERO_TOL sigma_1 > RANK_RTOL sigma_1: E has full column rank, the dense rule keeps
    every direction and x is the unique least-squares solution;
  - x comes from the corrected semi-normal equations: x = F^-1 E^T b, then REFINE
    corrections dx = F^-1 E^T (b - E x) with the residual taken on E itself (F = G -
    tau I; each correction removes the shift and the rounding of the squared system).
    The last correction must be at most CONVERGED ||x||.

  A record with an eigenvalue below tau (redundant reactions, or a near-singular
  balance), an off-diagonal pivot, or a refinement that does not settle is solved
  densely instead, so the answer is the dense rule's wherever the sparse way is not
  certified. Its cost is a sparse factorisation of the unknowns' size per record, and
  it never holds more than one record's E.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

# Relative singular value of E (its largest = 1) below which a direction counts as
# lost: redundant constraints give singular values at the level of the recorded
# constraint error (~1e-11 of a length), real ones are O(1) in N and N m per metre.
RANK_RTOL = 1e-8
# The sparse certificate: no singular value below this fraction of the largest (the
# shift tau = ZERO_TOL^2 s^2 sits above the rounding of G, eps ||G|| ~ 1e-16 s^2).
ZERO_TOL = 1e-7
REFINE = 3               # corrections of the semi-normal solution
CONVERGED = 1e-10        # the last correction, relative to ||x||, to accept a record
DENSE_UNKNOWNS = 48      # systems this small take the dense SVD (vectorised)
RETRY_AFTER = 16         # records between sparse attempts after one that failed


def solve_dense(E: np.ndarray, b: np.ndarray):
    """(x, rank per record): minimum-norm least-squares x of E x = b, E (n, rows,
    unknowns) dense, by the SVD of each record."""
    if E.shape[2] == 0:
        return np.zeros((len(b), 0)), np.zeros(len(b), int)
    U, s, Vt = np.linalg.svd(E, full_matrices=False)
    keep = s > RANK_RTOL * s[:, :1]
    inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    y = np.einsum("nki,nk->ni", U, b) * inv
    return np.einsum("nij,ni->nj", Vt, y), keep.sum(axis=1)


def solve_sparse(E: sp.csr_matrix, b: np.ndarray) -> np.ndarray | None:
    """x of one record by the certified sparse way (module docstring), None when it
    cannot certify the record (the caller solves it densely)."""
    m = E.shape[1]
    G = (E.T @ E).tocsc()
    scale = float(abs(G).sum(axis=0).max()) if G.nnz else 0.0
    if scale <= 0.0 or not np.isfinite(scale):
        return None
    tau = ZERO_TOL ** 2 * scale
    try:
        lu = splu((G - tau * sp.identity(m, format="csc")).tocsc(),
                  permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options=dict(SymmetricMode=True))
    except RuntimeError:                       # exactly singular
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c) or np.any(lu.U.diagonal() <= 0.0):
        return None
    Et = E.T.tocsr()
    x = lu.solve(Et @ b)
    for _ in range(REFINE):
        dx = lu.solve(Et @ (b - E @ x))
        x += dx
    if not (np.all(np.isfinite(x))
            and np.linalg.norm(dx) <= CONVERGED * max(np.linalg.norm(x), 1e-300)):
        return None
    return x


def solve_records(system, sparse: bool | None = None):
    """(x (n, unknowns), rank per record, records solved densely, max |E x - b|) of a
    :class:`~fccgen.mechanism.reaction_system.System`. sparse None: the sparse way
    for systems of more than DENSE_UNKNOWNS unknowns; True/False forces it. After a
    record the sparse way could not certify, the next RETRY_AFTER - 1 records go
    straight to the dense SVD (a model with redundant reactions fails it everywhere)."""
    n, m = system.n, system.shape[1]
    if sparse is None:
        sparse = m > DENSE_UNKNOWNS
    if not sparse or m == 0:
        E = system.dense()
        x, rank = solve_dense(E, system.b)
        r = np.einsum("nij,nj->ni", E, x) - system.b
        return x, rank, n, float(np.max(np.abs(r))) if r.size else 0.0
    x = np.zeros((n, m))
    rank = np.full(n, m)
    dense, worst, skip = 0, 0.0, 0
    for k in range(n):
        E, found = system.matrix(k), None
        if skip:
            skip -= 1
        else:
            found = solve_sparse(E, system.b[k])
            skip = 0 if found is not None else RETRY_AFTER - 1
        if found is None:
            xk, rk = solve_dense(E.toarray()[None], system.b[k:k + 1])
            found, rank[k] = xk[0], rk[0]
            dense += 1
        x[k] = found
        r = E @ found - system.b[k]
        if r.size:
            worst = max(worst, float(np.max(np.abs(r))))
    return x, rank, dense, worst
