"""Which rows of a large constraint Jacobian to keep, and which take part in its
dependencies: a basis of the row space from a certified LU (checked by
fccgen.rank.decide) and the weights of each redundant row's dependency."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from . import decide
from .rule import AMBIGUOUS_LOW


def independent_rows(C, rank: int) -> np.ndarray | None:
    """``rank`` rows of C (rows already scaled) that are independent by fccgen.rank's
    rule, or None when the choice cannot be certified.

    The pivot rows of an LU with partial pivoting of C (m x n, m >= n: P C = L U, dense
    LAPACK getrf, a third of the flops of the QR with column pivoting and blocked),
    without the pivot rows of the columns whose |U_jj| is at or below AMBIGUOUS_LOW
    max |U_jj| (a column depending on earlier ones gets a pivot of rounding size).
    Partial pivoting does not reveal rank in every case, so the choice S is checked:
    :func:`fccgen.rank.decide` of C[S] must give rank |S| = rank. Then every other row
    is a combination of S, and S is what the QR's first ``rank`` pivots would be: a
    basis of the row space."""
    import scipy.linalg
    m, n = C.shape
    if rank <= 0 or m < n:
        return None
    # row i of C is row perm[i] of L U: the pivot of column j is row argsort(perm)[j]
    perm, _, U = scipy.linalg.lu(C.toarray(), p_indices=True, check_finite=False)
    u = np.abs(np.diag(U))
    if not u.size or u.max() <= 0.0:
        return None
    kept = np.flatnonzero(u > AMBIGUOUS_LOW * u.max())
    rows = np.sort(np.argsort(perm)[kept])
    if rows.size != rank or decide(C[rows], n).rank != rank:
        return None
    return rows


def dependency_weights(Bs, keep: np.ndarray) -> np.ndarray:
    """||N^T e_k|| for every row k of Bs (rows scaled; N an orthonormal basis of its
    left null space), given ``keep``, a basis of its rows (:func:`independent_rows`),
    without the SVD of Bs (fccgen.mechanism.report.dependent_rows).

    The other rows R are combinations Bs_R = X Bs_S of the basis S: X^T solves
    Bs_S^T X^T = Bs_R^T (consistent, full column rank), taken from the augmented
    system [[I, Bs_S^T], [Bs_S, 0]] [res; X^T] = [Bs_R^T; 0] (one sparse LU, conditioned
    as Bs_S, not squared). The left null space is spanned by the columns of Y (rows S:
    -X^T, rows R: the identity), so with W = Y^T Y = I + X X^T (its size: the number
    of redundant rows) the weights are ||N^T e_k||^2 = y_k^T W^-1 y_k: for k in R the
    diagonal of W^-1, for k in S the squared column norms of L^-1 X (W = L L^T)."""
    import scipy.linalg
    m, n = Bs.shape
    redundant = np.setdiff1d(np.arange(m), keep)
    weights = np.zeros(m)
    if not redundant.size:
        return weights
    BS, BR = Bs[keep], Bs[redundant]
    r = keep.size
    K = sp.bmat([[sp.identity(n), BS.T], [BS, None]], format="csc")
    rhs = np.asfortranarray(np.vstack([BR.T.toarray(), np.zeros((r, redundant.size))]))
    # MMD on K^T K: a tenth of the fill of the default order on the mast's K
    X = splu(K, permc_spec="MMD_ATA").solve(rhs)[n:].T   # (redundant, r)
    L = np.linalg.cholesky(np.eye(redundant.size) + X @ X.T)
    Linv_X = scipy.linalg.solve_triangular(L, X, lower=True, check_finite=False)
    Linv = scipy.linalg.solve_triangular(L, np.eye(redundant.size), lower=True,
                                         check_finite=False)
    weights[keep] = np.linalg.norm(Linv_X, axis=0)
    weights[redundant] = np.linalg.norm(Linv, axis=0)
    return weights


